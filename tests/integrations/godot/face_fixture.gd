# A face for the tests, built in code (godot3-server cannot import glTF): a MeshInstance whose
# ArrayMesh has one blend shape per given name, each moving one vertex, under a root node.
extends Reference


static func make_face(shape_names, node_name = "Face"):
	var mesh = ArrayMesh.new()
	for name in shape_names:
		mesh.add_blend_shape(name)
	var arrays = []
	arrays.resize(Mesh.ARRAY_MAX)
	var base = PoolVector3Array([Vector3(0, 0, 0), Vector3(1, 0, 0), Vector3(0, 1, 0)])
	arrays[Mesh.ARRAY_VERTEX] = base
	var shapes = []
	for i in range(shape_names.size()):
		var moved = PoolVector3Array([Vector3(0, 0, 0.01 * (i + 1)), Vector3(1, 0, 0), Vector3(0, 1, 0)])
		var shape = []
		shape.resize(Mesh.ARRAY_MAX)
		shape[Mesh.ARRAY_VERTEX] = moved
		shapes.append(shape)
	mesh.add_surface_from_arrays(Mesh.PRIMITIVE_TRIANGLES, arrays, shapes)
	var face = MeshInstance.new()
	face.name = node_name
	face.mesh = mesh
	return face


# A silent 16-bit mono AudioStreamSample of `seconds` (Godot 3 cannot load a WAV without the editor's
# import; a real game would ship the imported WAV).
static func make_silence(seconds, mix_rate = 22050):
	var sample = AudioStreamSample.new()
	sample.format = AudioStreamSample.FORMAT_16_BITS
	sample.mix_rate = mix_rate
	sample.stereo = false
	var data = PoolByteArray()
	data.resize(int(seconds * mix_rate) * 2)
	for i in range(data.size()):
		data[i] = 0
	sample.data = data
	return sample


static func read_json(path):
	var file = File.new()
	if file.open(path, File.READ) != OK:
		return null
	var parsed = JSON.parse(file.get_as_text())
	file.close()
	return parsed.result if parsed.error == OK else null
