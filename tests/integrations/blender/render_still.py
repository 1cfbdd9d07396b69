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

import json
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import face_scene  # noqa: E402

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
face = face_scene.build_face(face_json, track["arkit_names"])
face.rotation_euler = (math.radians(90), 0, 0)  # the face's +y is up, +z its front: Blender's z up, -y front
for polygon in face.data.polygons:
    polygon.use_smooth = True

# One material per part of the face asset (skin, inner lip, cavity, teeth, tongue), by the part
# most of a triangle's vertices belong to.
with open(face_json, encoding="utf-8") as stream:
    parts = json.load(stream)["parts"]
colours = [(0.80, 0.55, 0.45), (0.62, 0.22, 0.22), (0.20, 0.03, 0.04), (0.92, 0.90, 0.85),
           (0.92, 0.90, 0.85), (0.75, 0.30, 0.32)]
for index, colour in enumerate(colours):
    material = bpy.data.materials.new(f"part{index}")
    material.use_nodes = True
    bsdf = material.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.55
    face.data.materials.append(material)
for polygon in face.data.polygons:
    votes = [parts[v] for v in polygon.vertices]
    polygon.material_index = max(set(votes), key=votes.count)

camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
camera.location = (0.0, -0.42, 0.0)
camera.rotation_euler = (math.radians(90), 0, 0)
camera.data.lens = 50
scene.collection.objects.link(camera)
scene.camera = camera
for name, location, energy in (("Key", (-0.3, -0.5, 0.35), 14.0), ("Fill", (0.4, -0.4, 0.0), 5.0)):
    light = bpy.data.objects.new(name, bpy.data.lights.new(name, "POINT"))
    light.data.energy = energy
    light.location = location
    scene.collection.objects.link(light)
world = bpy.data.worlds.new("World")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.18, 0.2, 0.24, 1.0)
scene.world = world

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
