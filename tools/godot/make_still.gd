# A still of the Godot add-on at work, for docs/integrations.md: lipsyncd's viewer face
# (data/face/viewer_face.json: the physics face's rest pose with ARKit blend shapes fitted to it)
# built as an ArrayMesh, a LipsyncPlayer showing a track at one instant, rendered by Godot 3 under
# Xvfb (the headless runtime draws nothing). Run by tools/godot/make_still.sh.
#   godot3 --path PROJECT --resolution 480x360 -s res://make_still.gd -- FACE TRACK T_US OUT.png
extends SceneTree

const LipsyncPlayer = preload("res://addons/lipsync/lipsync_player.gd")
const kPartColours = [Color(0.86, 0.68, 0.58), Color(0.62, 0.27, 0.28), Color(0.25, 0.08, 0.08),
		Color(0.95, 0.94, 0.88), Color(0.95, 0.94, 0.88), Color(0.75, 0.35, 0.38)]

var _frames_left = 8
var _out = ""


func _read_json(path):
	var file = File.new()
	if file.open(path, File.READ) != OK:
		return null
	var parsed = JSON.parse(file.get_as_text())
	file.close()
	return parsed.result if parsed.error == OK else null


# The viewer face in metres, one blend shape per fitted ARKit weight, coloured by part.
func _make_face(doc):
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


func _init():
	var args = Array(OS.get_cmdline_args())
	var at = args.find("--")
	if at < 0 or args.size() < at + 5:
		push_error("usage: -s res://make_still.gd -- FACE TRACK T_US OUT.png")
		quit(2)
		return
	var doc = _read_json(args[at + 1])
	if doc == null:
		push_error("cannot read the face " + args[at + 1])
		quit(1)
		return
	_out = args[at + 4]
	var face = _make_face(doc)
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
	var player = LipsyncPlayer.new()
	player.mesh_path = face.get_path()
	root.add_child(player)
	if player.load_track(args[at + 2]) != OK:
		quit(1)
		return
	player.show_at(int(args[at + 3]))


func _idle(_delta):
	_frames_left -= 1
	if _frames_left > 0:
		return false
	var image = root.get_texture().get_data()
	image.flip_y()
	var status = image.save_png(_out)
	quit(0 if status == OK else 1)
	return true
