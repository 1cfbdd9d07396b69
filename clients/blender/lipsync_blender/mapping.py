"""Which track curve drives which shape key, without Blender.

By default every ARKit weight of the track drives the shape key of the same name (Apple's
spelling, ``jawOpen``; a case-insensitive match such as ``JawOpen`` is accepted when there is
no exact one). A mapping file (JSON) changes that for a rig with names of its own:

    {"shape_keys": {"jawOpen": "Jaw_Open",
                    "mouthSmileLeft": ["Smile_L", "CheekRaise_L"],
                    "jaw_rotation": "JawDrop",
                    "eyeBlinkLeft": null}}

A key is an ARKit name or a model channel name of the track; the value is a shape key, a list
of shape keys, or null (not keyed, not reported). Names the mapping does not mention keep the
default. A mapping that names a curve the track does not have (a track of another model), or
a shape key the mesh does not have, is an error; so is one shape key driven by two curves.

resolve() returns the (curve, shape key) pairs to key and the ARKit names left without a shape
key, which the operator reports.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple

from .track import Track


class MappingError(ValueError):
    """A mapping file that cannot be used, or one that does not fit the track or the mesh."""


#: curve name -> shape key names ([] = deliberately not keyed)
Mapping = Dict[str, List[str]]


def parse_mapping(text: str, source: str) -> Mapping:
    try:
        document = json.loads(text)
    except json.JSONDecodeError as error:
        raise MappingError(f"{source}:{error.lineno}: not valid JSON ({error.msg})") from None
    if not isinstance(document, dict) or not isinstance(document.get("shape_keys"), dict):
        raise MappingError(f"{source}: a mapping file is a JSON object with a \"shape_keys\" object "
                           "(curve name -> shape key name, list of names, or null)")
    unknown = sorted(set(document) - {"shape_keys", "format", "version", "about"})
    if unknown:
        raise MappingError(f"{source}: unknown field {unknown[0]!r} (fields: shape_keys, about)")
    mapping: Mapping = {}
    for name, target in document["shape_keys"].items():
        if target is None:
            mapping[name] = []
        elif isinstance(target, str) and target:
            mapping[name] = [target]
        elif isinstance(target, list) and target and all(isinstance(t, str) and t for t in target):
            mapping[name] = list(target)
        else:
            raise MappingError(f"{source}: shape_keys[{name!r}] is {target!r}: give a shape key name, "
                               "a list of names, or null")
    return mapping


def read_mapping(path: str) -> Mapping:
    try:
        with open(path, encoding="utf-8") as stream:
            text = stream.read()
    except (OSError, UnicodeDecodeError) as error:
        raise MappingError(f"{path}: cannot read the mapping file: {error}") from None
    return parse_mapping(text, path)


@dataclass
class Resolution:
    pairs: List[Tuple[str, str]]   # (curve name, shape key name), in the track's order
    unmapped: List[str]            # ARKit names of the track with no shape key


def resolve(track: Track, shape_keys: Sequence[str], mapping: Optional[Mapping] = None,
            mapping_source: str = "mapping") -> Resolution:
    """Pairs the track's curves with the mesh's shape keys (the reference key excluded)."""
    mapping = mapping or {}
    available = set(shape_keys)
    by_folded: Dict[str, List[str]] = {}
    for name in shape_keys:
        by_folded.setdefault(name.casefold(), []).append(name)
    for name, targets in mapping.items():
        if track.curve(name) is None:
            model = f"model {track.model!r}" if track.model else track.layout
            raise MappingError(
                f"{mapping_source}: {name!r} is not a curve of the track {track.describe()} ({model}): "
                "a mapping names the track's ARKit weights or its model's channels; render the "
                "track with the model the mapping was written for")
        for target in targets:
            if target not in available:
                raise MappingError(f"{mapping_source}: {name!r} maps to shape key {target!r}, which the "
                                   "mesh does not have: add it or fix the mapping")
    pairs: List[Tuple[str, str]] = []
    unmapped: List[str] = []
    for name in list(track.arkit) + list(track.channels):
        if name in mapping:
            pairs.extend((name, target) for target in mapping[name])
            continue
        if name not in track.arkit:
            continue  # model channels drive shape keys only through a mapping
        if name in available:
            pairs.append((name, name))
        elif len(by_folded.get(name.casefold(), [])) == 1:
            pairs.append((name, by_folded[name.casefold()][0]))
        else:
            unmapped.append(name)
    driven: Dict[str, str] = {}
    for name, target in pairs:
        if target in driven:
            raise MappingError(f"{mapping_source}: shape key {target!r} would be driven by both "
                               f"{driven[target]!r} and {name!r}: map one of them elsewhere or to null")
        driven[target] = name
    return Resolution(pairs, unmapped)
