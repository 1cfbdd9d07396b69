"""The test face for Blender: the viewer's blendshape face with the 52 ARKit shape keys.

data/face/viewer_face.json is the physics face (MediaPipe canonical mesh, 771 vertices) with
27 mouth blendshapes fitted to lipsyncd's simulated speech (docs/face.md). Its rest shape and
those deltas become a mesh with a Basis key and one shape key per ARKit name of a track; the 25
names the face does not move (eyes, brows) get a key with no offset, so that the mesh carries
all 52 as an ARKit-rigged character does. Runs inside Blender (tests and the docs' still).
"""

import json

import bpy


def build_face(face_json_path, arkit_names, name="Face"):
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
