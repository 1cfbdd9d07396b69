"""Putting a track on a mesh's shape keys and its audio in the sequencer, all or nothing.

Every frame of the track becomes a key on every driven shape key's F-curve, at
``start_frame + t_us × fps / (fps_base × 10⁶)``: a fractional frame where the scene's rate
does not hit the track's time (closure key frames rarely fall on a frame), so no key frame is
lost to resampling. Keys are LINEAR, as the track's format asks of an interpolating engine.
The F-curves go into a new action that becomes the active action of the mesh's Key datablock
(glTF export takes shape-key animation from there, not from NLA strips); a previously active
action gets a fake user so that it is not lost on save.

apply() checks what it can first and then changes the scene; if anything fails after the
first change, everything it created is removed and the Key's animation restored, so the
scene is as it was.
"""

from __future__ import annotations

import math
import os
import struct
import wave
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import bpy

from .track import Track


class KeyingError(ValueError):
    """The scene or the mesh cannot take the track; the message says what to do."""


@dataclass
class Applied:
    action: "bpy.types.Action"
    keyed: List[Tuple[str, str]]
    frames: List[float]
    sound_strip: Optional["bpy.types.Sequence"] = None
    replaced_action: Optional[str] = None
    frame_end_extended: Optional[int] = None
    notes: List[str] = field(default_factory=list)


def shape_key_names(obj) -> List[str]:
    """The object's shape keys except the reference (Basis) key."""
    key = getattr(obj.data, "shape_keys", None) if obj is not None else None
    if key is None:
        return []
    reference = key.reference_key.name if key.reference_key else None
    return [kb.name for kb in key.key_blocks if kb.name != reference]


def check_mesh(obj) -> None:
    if obj is None:
        raise KeyingError("No active object: select the mesh whose shape keys the track should drive")
    if obj.type != "MESH":
        raise KeyingError(f"The active object {obj.name!r} is a {obj.type.lower()}, not a mesh: "
                          "select a mesh with ARKit shape keys")
    if not shape_key_names(obj):
        raise KeyingError(f"The mesh {obj.name!r} has no shape keys: add shape keys named after "
                          "ARKit's blendshapes (jawOpen, mouthClose, ...) or give a mapping file "
                          "from the track's names to its own")


def frames_of(track: Track, scene, start_frame: int) -> List[float]:
    """Scene frames of the track's times; refuses two times that float32 frames cannot tell apart."""
    rate = scene.render.fps / scene.render.fps_base
    frames = [start_frame + t_us * rate / 1e6 for t_us in track.times_us]
    as_f32 = struct.unpack(f"<{len(frames)}f", struct.pack(f"<{len(frames)}f", *frames))
    for i in range(1, len(as_f32)):
        if as_f32[i] <= as_f32[i - 1]:
            raise KeyingError(f"Frames {i - 1} and {i} of the track ({track.times_us[i - 1]} and "
                              f"{track.times_us[i]} µs) fall on the same Blender frame "
                              f"{as_f32[i]:.6f}: start the track at an earlier frame")
    return frames


def check_sound(path: str) -> None:
    if not os.path.isfile(path):
        raise KeyingError(f"Audio file {path!r} does not exist: choose the WAV that was spoken, or none")
    if path.lower().endswith(".wav"):
        try:
            with wave.open(path, "rb") as stream:
                stream.getnframes()
        except (wave.Error, EOFError, OSError) as error:
            raise KeyingError(f"Audio file {path!r} is not a readable WAV ({error})") from None


def _free_channel(editor) -> int:
    used = [s.channel for s in editor.sequences_all]
    return (max(used) + 1) if used else 1


def apply(scene, obj, track: Track, pairs: Sequence[Tuple[str, str]], start_frame: int,
          action_name: str, sound_path: Optional[str] = None, extend_frame_range: bool = True) -> Applied:
    """Keys `pairs` (curve name, shape key name) of `track` on `obj` and adds the sound strip."""
    check_mesh(obj)
    if not pairs:
        raise KeyingError("Nothing to key: none of the track's curves has a shape key on "
                          f"{obj.name!r}")
    if sound_path:
        check_sound(sound_path)
    frames = frames_of(track, scene, start_frame)
    key = obj.data.shape_keys
    had_animation = key.animation_data is not None
    previous = key.animation_data.action if had_animation else None
    previous_fake_user = previous.use_fake_user if previous else False
    had_editor = scene.sequence_editor is not None
    previous_frame_end = scene.frame_end
    action = None
    strip = None
    try:
        action = bpy.data.actions.new(action_name)
        action.id_root = "KEY"
        count = len(frames)
        for curve_name, shape_key in pairs:
            values = track.curve(curve_name)
            data_path = f'key_blocks["{bpy.utils.escape_identifier(shape_key)}"].value'
            fcurve = action.fcurves.new(data_path, action_group="lipsync")
            fcurve.keyframe_points.add(count)
            coordinates = [0.0] * (2 * count)
            coordinates[0::2] = frames
            coordinates[1::2] = values
            fcurve.keyframe_points.foreach_set("co", coordinates)
            fcurve.keyframe_points.foreach_set("interpolation", [1] * count)  # LINEAR
            fcurve.update()
        if not had_animation:
            key.animation_data_create()
        if previous is not None:
            previous.use_fake_user = True
        key.animation_data.action = action
        if sound_path:
            editor = scene.sequence_editor or scene.sequence_editor_create()
            strip = editor.sequences.new_sound(os.path.basename(sound_path), sound_path,
                                               _free_channel(editor), start_frame)
        applied = Applied(action, list(pairs), frames, strip,
                          previous.name if previous is not None else None)
        last = int(math.ceil(frames[-1]))
        if extend_frame_range and last > scene.frame_end:
            scene.frame_end = last
            applied.frame_end_extended = last
        return applied
    except Exception:
        if strip is not None:
            sound = strip.sound
            scene.sequence_editor.sequences.remove(strip)
            if sound is not None and sound.users == 0:
                bpy.data.sounds.remove(sound)
        if not had_editor and scene.sequence_editor is not None:
            scene.sequence_editor_clear()
        scene.frame_end = previous_frame_end
        if key.animation_data is not None:
            if had_animation:
                key.animation_data.action = previous
            else:
                key.animation_data_clear()
        if previous is not None:
            previous.use_fake_user = previous_fake_user
        if action is not None:
            bpy.data.actions.remove(action)
        raise
