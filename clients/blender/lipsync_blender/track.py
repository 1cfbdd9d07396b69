"""Reading a lipsyncd track file into named curves, without Blender.

A track (docs/output-formats.md) is a list of frames at exact, strictly increasing times in
integer microseconds; each frame carries the 52 ARKit weights and/or the model's channel
values. This module reads the three layouts lipsyncd writes that carry such curves:

* ``json`` (``"format": "lipsync-track"``): times from ``t_us``, the frame kinds, the ARKit
  weights under Apple's names and the model channels under the model's names;
* ``arkit-csv`` (Unreal Live Link Face CSV): times from the ``HH:MM:SS:FF.fff`` timecode at
  the frame rate the track was rendered at (the file does not say it; a rate that does not fit
  the timecodes is refused), PascalCase names
  turned back into Apple's (``JawOpen`` -> ``jawOpen``); the nine head and eye rotation
  columns are not blendshapes and are left out;
* ``csv`` (model channels): times from ``t_us``, kinds, the channels.

Everything wrong with a file is a TrackError naming the file, line or frame and field, with
what to do about it; a file of another kind (a WAV, Rhubarb cues, other JSON, and a phoneme
file in any of the six formats lipsync reads, told apart by lipsync's own content rules,
docs/input-formats.md "Detection") is named as such. Values stay Python floats (the float32 text reads back to the same float32 in Blender).
"""

from __future__ import annotations

import csv
import io
import json
import os
import re
import shlex
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

#: The Live Link Face CSV's rotation columns: not blendshapes (always 0 in lipsyncd's output).
ROTATION_COLUMNS = (
    "HeadYaw", "HeadPitch", "HeadRoll",
    "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll",
    "RightEyeYaw", "RightEyePitch", "RightEyeRoll",
)

_TIMECODE = re.compile(r"^(\d+):(\d{2}):(\d{2}):(\d+)(?:\.(\d{1,3}))?$")
_RENDER_HINT = "render one with `lipsync render INPUT --format json` (or arkit-csv)"

#: The phoneme formats lipsync reads (docs/input-formats.md), as the messages name them.
PHONEME_FORMATS = {
    "json": "lipsync utterance JSON",
    "textgrid": "a Praat TextGrid",
    "timit": "a TIMIT .PHN file",
    "lab": "a Festival .lab file",
    "pho": "an MBROLA .pho file",
    "flite": "`flite -psdur` output",
}
#: The ones Render Phonemes with lipsyncd reads itself (live.read_phonemes).
_LIVE_PHONEME_FORMATS = ("json", "flite")
_PHONEME_EXTENSIONS = {".textgrid": "textgrid", ".phn": "timit", ".lab": "lab",
                       ".pho": "pho", ".psdur": "flite", ".flite": "flite"}
_DECIMAL = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_INTEGER = re.compile(r"[+-]?\d+")


class TrackError(ValueError):
    """A track file that cannot be used; the message names the file and where."""


@dataclass
class Track:
    """Named curves over one time line.

    times_us: frame times, integer µs, strictly increasing; kinds: each frame's kind
    ("uniform", "closure_start", "closure_end", "short_segment") or None where the file does
    not say (arkit-csv); arkit: Apple's ARKit name -> one weight per frame; channels: model
    channel name -> one value per frame; model and fps as the file states them (None if not).
    """

    source: str
    layout: str
    times_us: List[int]
    kinds: List[Optional[str]]
    arkit: Dict[str, List[float]] = field(default_factory=dict)
    channels: Dict[str, List[float]] = field(default_factory=dict)
    model: Optional[str] = None
    fps: Optional[int] = None

    def curve(self, name: str) -> Optional[List[float]]:
        """The curve of an ARKit name or a channel name (ARKit first), else None."""
        if name in self.arkit:
            return self.arkit[name]
        return self.channels.get(name)

    def describe(self) -> str:
        model = f", model {self.model!r}" if self.model else ""
        return (f"{os.path.basename(self.source)} ({self.layout}{model}, {len(self.times_us)} frames, "
                f"{len(self.arkit)} ARKit weights, {len(self.channels)} channels)")


def _check_times(source: str, times_us: List[int], where) -> None:
    for i in range(1, len(times_us)):
        if times_us[i] <= times_us[i - 1]:
            raise TrackError(f"{source}: {where(i)}: time {times_us[i]} µs is not after the previous "
                             f"frame's {times_us[i - 1]} µs (track times must strictly increase)")


def _number(source: str, where: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise TrackError(f"{source}: {where}: {text!r} is not a number") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise TrackError(f"{source}: {where}: value {text!r} is not finite")
    return value


def _is_timit_line(line: str) -> bool:
    fields = line.split()
    return len(fields) == 3 and bool(_INTEGER.fullmatch(fields[0]) and _INTEGER.fullmatch(fields[1]))


def _is_lab_line(line: str) -> bool:
    fields = line.split()
    return len(fields) == 3 and bool(_DECIMAL.fullmatch(fields[0]) and _INTEGER.fullmatch(fields[1]))


def _is_flite_line(line: str) -> bool:
    return all(token.rfind(":") > 0 for token in line.split())


def _has_flite_time(line: str) -> bool:
    return any(":" in token and _DECIMAL.fullmatch(token.rsplit(":", 1)[1]) for token in line.split())


def _is_pho_line(line: str) -> bool:
    fields = line.split(";", 1)[0].split()
    if not fields or fields == ["#"]:
        return True
    return len(fields) >= 2 and len(fields) % 2 == 0 and \
        all(_DECIMAL.fullmatch(f[:-1] if f.endswith("%") else f) for f in fields[1:])


def phoneme_format(text: str, path: str = "") -> Optional[str]:
    """The phoneme format lipsync would read `text`, which is not JSON, as (a key of
    PHONEME_FORMATS), or None: lipsync's own detection (core/src/formats/detect.cpp), on the
    first 40 non-blank lines, the content first, then the file name's extension."""
    start = text.strip()
    first_line = re.split(r"\r\n|\r|\n", start, maxsplit=1)[0]
    if '"ooTextFile' in first_line or '"Praat chronological TextGrid text file"' in first_line:
        return "textgrid"
    lines = re.split(r"\r\n|\r|\n", text)

    def sample(begin=0):
        return [line for line in lines[begin:] if line.strip()][:40]

    head = sample()
    if head and all(_is_timit_line(line) for line in head):
        return "timit"
    hashes = [i for i, line in enumerate(lines) if line.strip() == "#"]
    if hashes and hashes[0] < 40:
        after = sample(hashes[0] + 1)
        if after and all(_is_lab_line(line) for line in after):
            return "lab"
    if head and all(_is_lab_line(line) for line in head) and any("." in line.split()[0] for line in head):
        return "lab"
    if head and all(_is_flite_line(line) for line in head) and any(_has_flite_time(line) for line in head):
        return "flite"
    if any(len(line.split(";", 1)[0].split()) >= 2 for line in head) and all(_is_pho_line(line) for line in head):
        return "pho"
    return _PHONEME_EXTENSIONS.get(os.path.splitext(path)[1].lower()) if path else None


def phoneme_file_error(source: str, phoneme_format: str) -> TrackError:
    """The error for a phoneme file given as a track: what it is, and how to get its track."""
    name = os.path.basename(source)
    stem, extension = os.path.splitext(name)
    out = stem + ("_track.json" if extension.lower() == ".json" else ".json")
    way = f"render it (`lipsync render {shlex.quote(name)} -o {shlex.quote(out)}`) and import {out}"
    if phoneme_format in _LIVE_PHONEME_FORMATS:
        way += ", or use Render Phonemes with lipsyncd"
    return TrackError(f"{source}: not a lipsyncd track but a phoneme file "
                      f"({PHONEME_FORMATS[phoneme_format]}: lipsyncd's input, not its output): {way}")


def _other_json_kind(document) -> Optional[str]:
    """What a JSON document is when it is not a track (None if unrecognised)."""
    if not isinstance(document, dict):
        return None
    if "mouthCues" in document:
        return "Rhubarb mouth cues (visemes A-H, X), which have no blendshape weights"
    if isinstance(document.get("format"), str) and document["format"] != "lipsync-track":
        return f"a {document['format']!r} file"
    return None


def parse_json_track(text: str, source: str) -> Track:
    try:
        document = json.loads(text)
    except json.JSONDecodeError as error:
        raise TrackError(f"{source}:{error.lineno}: not valid JSON ({error.msg})") from None
    if not isinstance(document, dict) or document.get("format") != "lipsync-track":
        if isinstance(document, dict) and "phonemes" in document:
            raise phoneme_file_error(source, "json")
        kind = _other_json_kind(document)
        found = kind or "JSON without \"format\": \"lipsync-track\""
        raise TrackError(f"{source}: not a lipsyncd track but {found}; {_RENDER_HINT}")
    if document.get("version") != 1:
        raise TrackError(f"{source}: track version {document.get('version')!r} is not supported "
                         "(this add-on reads version 1): update the add-on or render with this lipsyncd")
    names = {}
    for key in ("channels", "arkit_names"):
        value = document.get(key, [])
        if not isinstance(value, list) or not all(isinstance(n, str) for n in value):
            raise TrackError(f"{source}: field {key!r} must be a list of names")
        names[key] = value
    frames = document.get("frames")
    if not isinstance(frames, list) or not frames:
        raise TrackError(f"{source}: field 'frames' must be a non-empty list of frames")
    channels = {n: [] for n in names["channels"]}
    arkit = {n: [] for n in names["arkit_names"]}
    times, kinds = [], []
    for i, frame in enumerate(frames):
        where = f"frames[{i}]"
        if not isinstance(frame, dict):
            raise TrackError(f"{source}: {where} is not an object")
        t_us = frame.get("t_us")
        if not isinstance(t_us, int) or isinstance(t_us, bool) or t_us < 0:
            raise TrackError(f"{source}: {where}: 't_us' must be a non-negative integer (µs), "
                             f"found {t_us!r}")
        times.append(t_us)
        kinds.append(frame.get("kind") if isinstance(frame.get("kind"), str) else None)
        for key, curves, order in (("values", channels, names["channels"]),
                                   ("arkit", arkit, names["arkit_names"])):
            row = frame.get(key, [] if not order else None)
            if not isinstance(row, list) or len(row) != len(order):
                count = len(row) if isinstance(row, list) else "no"
                raise TrackError(f"{source}: {where}: {key!r} has {count} values for "
                                 f"{len(order)} names")
            for name, value in zip(order, row):
                if not isinstance(value, (int, float)) or isinstance(value, bool):
                    raise TrackError(f"{source}: {where}: {key} value of {name!r} is {value!r}, "
                                     "not a number")
                curves[name].append(float(value))
    _check_times(source, times, lambda i: f"frames[{i}]")
    fps = document.get("fps") if isinstance(document.get("fps"), int) else None
    model = document.get("model") if isinstance(document.get("model"), str) else None
    return Track(source, "json", times, kinds, arkit, channels, model, fps)


def _split_timecode(source: str, line: int, text: str) -> Tuple[int, int, int]:
    """(whole seconds, frame, thousandths of a frame) of HH:MM:SS:FF.fff."""
    match = _TIMECODE.match(text.strip())
    if not match:
        raise TrackError(f"{source}:{line}: Timecode {text!r} is not HH:MM:SS:FF.fff")
    hours, minutes, seconds, frame = (int(match.group(i)) for i in range(1, 5))
    millis = int((match.group(5) or "0").ljust(3, "0"))
    return (hours * 60 + minutes) * 60 + seconds, frame, millis


def _timecode_to_us(timecode: Tuple[int, int, int], fps: int) -> int:
    seconds, frame, millis = timecode
    milliframes = frame * 1000 + millis
    # µs = milliframes / (fps × 1000) s, rounded half up, in integers.
    sub_us = (milliframes * 2_000_000 + fps * 1000) // (2 * fps * 1000)
    return seconds * 1_000_000 + sub_us


def _check_rate(source: str, body, timecodes, csv_fps: int) -> int:
    """csv_fps, checked against the timecodes.

    A frame number never reaches the rate. And a track at N frames/s has frames all through
    its first second (lipsyncd's frames are at most a couple of grid steps apart), so when the
    track goes past that second, its frame numbers there go well beyond N / 2: a rate twice too
    high or more shows. (The rate cannot be read from the timecodes in general: key frames
    fall anywhere, and at low rates around every second boundary.)
    """
    hint = "set the CSV frame rate to the rate the track was rendered at (`lipsync render --fps N`)"
    if csv_fps < 1:
        raise TrackError(f"{source}: a Live Link Face CSV needs its frame rate: {hint}")
    for (line, row), (_, frame, _) in zip(body, timecodes):
        if frame >= csv_fps:
            raise TrackError(f"{source}:{line}: Timecode {row[0]!r} has frame {frame} in a second of "
                             f"{csv_fps} frames: {hint}")
    if any(seconds >= 1 for seconds, _, _ in timecodes):
        highest = max(frame for seconds, frame, _ in timecodes if seconds == 0)
        if 2 * (highest + 1) <= csv_fps:
            raise TrackError(f"{source}: the first second's timecodes stop at frame {highest}, so the "
                             f"track is at about {highest + 1} frames/s, not {csv_fps}: {hint}")
    return csv_fps


def parse_csv_track(text: str, source: str, csv_fps: int = 60) -> Track:
    if not text.strip():
        raise TrackError(f"{source}: empty file; {_RENDER_HINT}")
    try:
        rows = list(csv.reader(io.StringIO(text)))
    except csv.Error as error:
        raise TrackError(f"{source}: not a lipsyncd track: not CSV ({error}); {_RENDER_HINT}") from None
    header = [h.strip() for h in rows[0]]
    if header[:2] != ["Timecode", "BlendShapeCount"] and header[:3] != ["t", "t_us", "kind"]:
        found = phoneme_format(text, source)
        if found:
            raise phoneme_file_error(source, found)
        raise TrackError(f"{source}:1: not a lipsyncd track: expected the header of a Live Link Face "
                         f"CSV (Timecode,BlendShapeCount,...) or a channel CSV (t,t_us,kind,...), found "
                         f"{','.join(header[:3])!r}...; {_RENDER_HINT}")
    body = [(n + 2, r) for n, r in enumerate(rows[1:]) if r]
    if not body:
        raise TrackError(f"{source}: a header and no frames")
    if header[:2] == ["Timecode", "BlendShapeCount"]:
        columns = [(i, h[:1].lower() + h[1:]) for i, h in enumerate(header)
                   if i >= 2 and h not in ROTATION_COLUMNS]
        arkit = {name: [] for _, name in columns}
        timecodes = []
        for line, row in body:
            if len(row) != len(header):
                raise TrackError(f"{source}:{line}: {len(row)} columns, the header has {len(header)}")
            timecodes.append(_split_timecode(source, line, row[0]))
            for i, name in columns:
                arkit[name].append(_number(source, f"line {line}, column {header[i]}", row[i]))
        fps = _check_rate(source, body, timecodes, csv_fps)
        times = [_timecode_to_us(timecode, fps) for timecode in timecodes]
        _check_times(source, times, lambda i: f"line {body[i][0]}")
        return Track(source, "arkit-csv", times, [None] * len(times), arkit, {}, None, fps)
    channels = {name: [] for name in header[3:]}
    times, kinds = [], []
    for line, row in body:
        if len(row) != len(header):
            raise TrackError(f"{source}:{line}: {len(row)} columns, the header has {len(header)}")
        if not re.fullmatch(r"\d+", row[1].strip()):
            raise TrackError(f"{source}:{line}: t_us {row[1]!r} is not an integer number of µs")
        times.append(int(row[1]))
        kinds.append(row[2].strip())
        for name, value in zip(header[3:], row[3:]):
            channels[name].append(_number(source, f"line {line}, column {name}", value))
    _check_times(source, times, lambda i: f"line {body[i][0]}")
    return Track(source, "csv", times, kinds, {}, channels, None, None)


def read_track(path: str, csv_fps: int = 60) -> Track:
    """Reads a track file; the layout comes from the content (JSON object or CSV header).
    csv_fps: the frame rate a Live Link Face CSV was rendered at (its timecodes count such frames)."""
    try:
        with open(path, "rb") as stream:
            data = stream.read()
    except OSError as error:
        raise TrackError(f"{path}: cannot read the track: {error.strerror}") from None
    if data[:4] == b"RIFF" and data[8:12] == b"WAVE":
        raise TrackError(f"{path}: not a lipsyncd track but a WAV file (audio): give it as the Audio "
                         "(WAV) and, as the file, the track `lipsync render` wrote for that speech")
    try:
        # Praat writes UTF-16 TextGrids (with a byte order mark): still named as phoneme files.
        text = data.decode("utf-16" if data[:2] in (b"\xff\xfe", b"\xfe\xff") else "utf-8-sig")
    except UnicodeDecodeError as error:
        raise TrackError(f"{path}: not a text file (byte {error.start} is not UTF-8; a lipsyncd "
                         f"track is JSON or CSV); {_RENDER_HINT}") from None
    if text.lstrip().startswith(("{", "[")):
        return parse_json_track(text, path)
    return parse_csv_track(text, path, csv_fps)
