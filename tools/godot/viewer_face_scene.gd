# lipsyncd's viewer face (data/face/viewer_face.json: the physics face's rest pose with ARKit blend
# shapes fitted to it) as a Godot 3 scene for the stills of docs/integrations.md: the face built
# as an ArrayMesh (a MeshInstance named "Face", coloured by part), and a camera, a light and a plain
# background before it. Used by make_still.gd (a track at one instant) and make_live_still.gd (a
# voice spoken live through listen()).
extends Reference

const Fixture = preload("res://face_fixture.gd")  # tests/integrations/godot/: read_json, read_wav

# By the face's `parts` (lipsync.v1.MeshPart): skin, inner lip, mouth cavity, upper and lower teeth,
# tongue, eye white, iris, pupil (the viewer page's colours, server/web/viewer.js, a little darker).
const kPartColours = [Color(0.86, 0.68, 0.58), Color(0.62, 0.27, 0.28), Color(0.25, 0.08, 0.08),
		Color(0.95, 0.94, 0.88), Color(0.95, 0.94, 0.88), Color(0.75, 0.35, 0.38),
		Color(0.93, 0.92, 0.88), Color(0.36, 0.24, 0.14), Color(0.03, 0.03, 0.03)]


# The viewer face in metres, one blend shape per fitted ARKit weight, coloured by part.
static func make_face(doc):
	var rest = doc["rest_um"]
	var vertices = PoolVector3Array()
	var colours = PoolColorArray()
	for v in range(int(doc["vertex_count"])):
		vertices.append(Vector3(rest[3 * v], rest[3 * v + 1], rest[3 * v + 2]) * 1e-6)
		colours.append(kPartColours[int(doc["parts"][v])])
	var indices = PoolIntArray()
	var triangles = doc["triangles"]
	for i in range(0, triangles.size(), 3):  # Godot's front faces wind clockwise
		indices.append(int(triangles[i]))
		indices.append(int(triangles[i + 2]))
		indices.append(int(triangles[i + 1]))
	var normals = PoolVector3Array()
	normals.resize(vertices.size())
	for v in range(vertices.size()):
		normals[v] = Vector3()
	for i in range(0, indices.size(), 3):
		var a = indices[i]
		var b = indices[i + 1]
		var c = indices[i + 2]
		var n = (vertices[c] - vertices[a]).cross(vertices[b] - vertices[a])
		normals[a] += n
		normals[b] += n
		normals[c] += n
	for v in range(vertices.size()):
		normals[v] = normals[v].normalized()
	var mesh = ArrayMesh.new()
	var shapes = []
	for shape in doc["blendshapes"]:
		mesh.add_blend_shape(shape["name"])
		var deltas = shape["deltas_um"]
		var moved = PoolVector3Array()
		for v in range(vertices.size()):
			moved.append(vertices[v] + Vector3(deltas[3 * v], deltas[3 * v + 1], deltas[3 * v + 2]) * 1e-6)
		var arrays = []
		arrays.resize(Mesh.ARRAY_MAX)
		arrays[Mesh.ARRAY_VERTEX] = moved
		arrays[Mesh.ARRAY_NORMAL] = normals
		arrays[Mesh.ARRAY_COLOR] = colours  # a blend shape has the surface's arrays but its indices
		shapes.append(arrays)
	var arrays = []
	arrays.resize(Mesh.ARRAY_MAX)
	arrays[Mesh.ARRAY_VERTEX] = vertices
	arrays[Mesh.ARRAY_NORMAL] = normals
	arrays[Mesh.ARRAY_COLOR] = colours
	arrays[Mesh.ARRAY_INDEX] = indices
	mesh.add_surface_from_arrays(Mesh.PRIMITIVE_TRIANGLES, arrays, shapes)
	var material = SpatialMaterial.new()
	material.vertex_color_use_as_albedo = true
	material.flags_unshaded = false
	material.params_cull_mode = SpatialMaterial.CULL_DISABLED
	mesh.surface_set_material(0, material)
	var face = MeshInstance.new()
	face.name = "Face"
	face.mesh = mesh
	return face


# The script's arguments after "--" (OS.get_cmdline_args()), `count` of them; null, with `usage`
# as an error, when there are fewer.
static func script_args(count, usage):
	var args = Array(OS.get_cmdline_args())
	var at = args.find("--")
	if at < 0 or args.size() < at + 1 + count:
		push_error("usage: " + usage)
		return null
	return args.slice(at + 1, at + count)


# The face of `face_path` (viewer_face.json) under `root` with the camera, the light and the
# background; the face's MeshInstance, or null (and an error) when the file does not read.
static func stage(root, face_path):
	var doc = Fixture.read_json(face_path)
	if doc == null:
		push_error("cannot read the face " + face_path)
		return null
	var face = make_face(doc)
	root.add_child(face)
	var camera = Camera.new()
	camera.translation = Vector3(0, -0.03, 0.42)
	camera.fov = 34
	root.add_child(camera)
	camera.make_current()
	var light = DirectionalLight.new()
	light.rotation_degrees = Vector3(-25, 20, 0)
	root.add_child(light)
	var environment = Environment.new()
	environment.background_mode = Environment.BG_COLOR
	environment.background_color = Color(0.16, 0.17, 0.2)
	environment.ambient_light_color = Color(0.55, 0.55, 0.6)
	var world = WorldEnvironment.new()
	world.environment = environment
	root.add_child(world)
	return face


# What `root`'s viewport last drew (the frame before this idle step), the right way up, as a PNG.
static func save_view(root, out_path):
	var image = root.get_texture().get_data()
	image.flip_y()
	return image.save_png(out_path)
