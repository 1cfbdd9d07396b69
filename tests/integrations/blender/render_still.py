"""Renders the stills of docs/integrations.md: the test face keyed by the add-on, in Cycles on the CPU.

    blender -b --factory-startup --python tests/integrations/blender/render_still.py -- \
        ADDON_ZIP TRACK.json FACE_JSON OUT_DIR [SAMPLES]

TRACK.json is the track of flite's "Papa bought five more big maps." (`flite -voice slt -psdur`
piped into `lipsync render - --phone-set radio --format json`). The add-on is installed from its
zip, imports the track on a scene of 1000 frames/s (so that a render, which takes whole frames,
lands on flite's millisecond times exactly), and two frames are rendered at 480 × 360: the closure key
frame that starts the first /p/ (lips sealed) and the middle of the /aa/ after it (mouth open),
as blender-closure-p.png and blender-open-aa.png. Not a test: the pictures are for the docs.
"""

import importlib.util
import json
import os
import sys

import bpy


def _load_demo_face():
    """clients/blender/demo_face.py, by its path: that folder on sys.path would hide the add-on
    installed from the zip behind its sources."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "clients", "blender",
                        "demo_face.py")
    spec = importlib.util.spec_from_file_location("demo_face", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


demo_face = _load_demo_face()

args = sys.argv[sys.argv.index("--") + 1:]
addon_zip, track_path, face_json, out_dir = args[:4]
samples = int(args[4]) if len(args) > 4 else 32

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.preferences.addon_install(filepath=addon_zip, overwrite=True)
bpy.ops.preferences.addon_enable(module="lipsync_blender")
scene = bpy.context.scene
scene.render.fps = 1000

with open(track_path, encoding="utf-8") as stream:
    track = json.load(stream)
face = demo_face.build_face(face_json, track["arkit_names"])
demo_face.dress(face, face_json)

result = bpy.ops.lipsync.import_track(filepath=track_path, start_frame=0)
assert result == {"FINISHED"}, result

scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = samples
scene.cycles.use_denoising = False
scene.render.resolution_x, scene.render.resolution_y = 480, 360
scene.render.resolution_percentage = 100
scene.render.image_settings.file_format = "PNG"
scene.render.image_settings.color_mode = "RGB"

frames = track["frames"]
first_p = next(f for f in frames if f["kind"] == "closure_start")
after = [f["t_us"] for f in frames if f["kind"] == "closure_end"][0]
next_closure = next(f["t_us"] for f in frames if f["kind"] == "closure_start" and f["t_us"] > after)
open_us = (after + next_closure) // 2000 * 1000
for name, t_us in (("blender-closure-p.png", first_p["t_us"]), ("blender-open-aa.png", open_us)):
    at = t_us // 1000
    scene.frame_set(at)
    scene.render.filepath = os.path.join(out_dir, name)
    bpy.ops.render.render(write_still=True)
    print(f"rendered {name} at {t_us} µs")
