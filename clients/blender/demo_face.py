"""The demo face for the Blender add-on: lipsyncd's viewer face with the 52 ARKit shape keys.

    blender -b --factory-startup --python clients/blender/demo_face.py -- face.blend [FACE_JSON]
    blender face.blend

writes face.blend: the face (active and selected, ready for File > Import > lipsyncd Track), a
camera looking at it, two lights, and the 3D view looking through the camera. FACE_JSON is
data/face/viewer_face.json, found beside this script in the sources or in an installation
(share/lipsync/blender/demo_face.py and share/lipsync/data/face/), unless given.

That file is the physics face (MediaPipe canonical mesh, 771 vertices) with 27 mouth
blendshapes fitted to lipsyncd's simulated speech (docs/face.md). Its rest shape and those
deltas become a mesh with a Basis key and one shape key per ARKit name; the 25 names the face
does not move (eyes, brows) get a key with no offset, so that the mesh carries all 52 as an
ARKit-rigged character does. The add-on's tests key tracks on the same mesh (build_face) and
tests/integrations/blender/render_still.py renders the docs' stills of the dressed face.
"""

import json
import math
import os
import sys

import bpy

#: Apple's 52 ARKit blendshape names, in the order lipsyncd's tracks list them.
ARKIT_NAMES = (
    "eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft",
    "eyeSquintLeft", "eyeWideLeft", "eyeBlinkRight", "eyeLookDownRight", "eyeLookInRight",
    "eyeLookOutRight", "eyeLookUpRight", "eyeSquintRight", "eyeWideRight", "jawForward", "jawLeft",
    "jawRight", "jawOpen", "mouthClose", "mouthFunnel", "mouthPucker", "mouthLeft", "mouthRight",
    "mouthSmileLeft", "mouthSmileRight", "mouthFrownLeft", "mouthFrownRight", "mouthDimpleLeft",
    "mouthDimpleRight", "mouthStretchLeft", "mouthStretchRight", "mouthRollLower", "mouthRollUpper",
    "mouthShrugLower", "mouthShrugUpper", "mouthPressLeft", "mouthPressRight", "mouthLowerDownLeft",
    "mouthLowerDownRight", "mouthUpperUpLeft", "mouthUpperUpRight", "browDownLeft", "browDownRight",
    "browInnerUp", "browOuterUpLeft", "browOuterUpRight", "cheekPuff", "cheekSquintLeft",
    "cheekSquintRight", "noseSneerLeft", "noseSneerRight", "tongueOut",
)

#: Colours of the face asset's parts (skin, inner lip, cavity, upper and lower teeth, tongue).
_PART_COLOURS = ((0.80, 0.55, 0.45), (0.62, 0.22, 0.22), (0.20, 0.03, 0.04), (0.92, 0.90, 0.85),
                 (0.92, 0.90, 0.85), (0.75, 0.30, 0.32))


def default_face_json():
    """data/face/viewer_face.json beside this script: in the sources (clients/blender/) or where
    `cmake --install` puts both (share/lipsync/blender/ and share/lipsync/data/)."""
    here = os.path.dirname(os.path.abspath(__file__))
    for up in (("..", ".."), ("..",)):
        path = os.path.normpath(os.path.join(here, *up, "data", "face", "viewer_face.json"))
        if os.path.isfile(path):
            return path
    return os.path.normpath(os.path.join(here, "..", "..", "data", "face", "viewer_face.json"))


def build_face(face_json_path, arkit_names=ARKIT_NAMES, name="Face"):
    """The face as a mesh object in the scene (rest shape in metres, +y up, +z its front), with a
    Basis key and one shape key per name; active and selected."""
    with open(face_json_path, encoding="utf-8") as stream:
        face = json.load(stream)
    rest = [v * 1e-6 for v in face["rest_um"]]  # metres
    count = face["vertex_count"]
    triangles = face["triangles"]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(rest[3 * i:3 * i + 3]) for i in range(count)], [],
                     [tuple(triangles[3 * i:3 * i + 3]) for i in range(len(triangles) // 3)])
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.shape_key_add(name="Basis")
    deltas = {b["name"]: b["deltas_um"] for b in face["blendshapes"]}
    for arkit_name in arkit_names:
        block = obj.shape_key_add(name=arkit_name, from_mix=False)
        delta = deltas.get(arkit_name)
        if delta is not None:
            block.data.foreach_set("co", [r + d * 1e-6 for r, d in zip(rest, delta)])
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    return obj


def dress(face, face_json_path):
    """Stands the face up in Blender's axes (z up, looking along -y), smooth-shaded with one
    material per part, and adds a camera in front of it, two lights and a grey world."""
    scene = bpy.context.scene
    face.rotation_euler = (math.radians(90), 0, 0)
    for polygon in face.data.polygons:
        polygon.use_smooth = True
    with open(face_json_path, encoding="utf-8") as stream:
        parts = json.load(stream)["parts"]
    for index, colour in enumerate(_PART_COLOURS):
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


def _look_through_camera():
    """The saved file's 3D views look through the camera (the face is 15 cm across: in the
    default view it would be a speck)."""
    for screen in bpy.data.screens:
        for area in screen.areas:
            if area.type == "VIEW_3D":
                area.spaces.active.region_3d.view_perspective = "CAMERA"


def main(argv):
    if not argv or not argv[0].endswith(".blend") or len(argv) > 2:
        sys.exit("usage: blender -b --factory-startup --python demo_face.py -- OUT.blend [FACE_JSON]")
    out = os.path.abspath(argv[0])
    face_json = argv[1] if len(argv) > 1 else default_face_json()
    if not os.path.isfile(face_json):
        sys.exit(f"{face_json}: no such face file; give data/face/viewer_face.json of lipsyncd's "
                 "sources or of its installation (share/lipsync/data/face/)")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    face = build_face(face_json)
    dress(face, face_json)
    _look_through_camera()
    bpy.ops.wm.save_as_mainfile(filepath=out)
    print(f"wrote {out}: the face {face.name!r} with {len(ARKIT_NAMES)} ARKit shape keys")


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
