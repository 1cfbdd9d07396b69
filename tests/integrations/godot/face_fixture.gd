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


# A face with a blend shape for each ARKit name of `track` (a parsed lipsyncd track).
static func make_face_for(track):
	var names = []
	for name in track["arkit_names"]:
		names.append(name)
	return make_face(names)


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


# A WAV file (RIFF, PCM 8- or 16-bit) as the AudioStreamSample Godot's importer makes of it (Godot 3
# cannot load a WAV at run time without the editor's import): 8-bit samples become signed, as the
# importer stores them. null for anything else.
static func read_wav(path):
	var file = File.new()
	if file.open(path, File.READ) != OK:
		return null
	var bytes = file.get_buffer(file.get_len())
	file.close()
	if bytes.size() < 12 or bytes.subarray(0, 3).get_string_from_ascii() != "RIFF" or bytes.subarray(8, 11).get_string_from_ascii() != "WAVE":
		return null
	var reader = StreamPeerBuffer.new()
	reader.data_array = bytes
	var sample = AudioStreamSample.new()
	var bits = 0
	var position = 12
	while position + 8 <= bytes.size():
		var id = bytes.subarray(position, position + 3).get_string_from_ascii()
		reader.seek(position + 4)
		var size = reader.get_u32()
		var body = position + 8
		if id == "fmt ":
			reader.seek(body)
			if reader.get_u16() != 1:  # PCM
				return null
			sample.stereo = reader.get_u16() == 2
			sample.mix_rate = reader.get_u32()
			reader.get_u32()  # bytes per second
			reader.get_u16()  # block align
			bits = reader.get_u16()
			sample.format = AudioStreamSample.FORMAT_16_BITS if bits == 16 else AudioStreamSample.FORMAT_8_BITS
		elif id == "data" and (bits == 8 or bits == 16):
			var data = bytes.subarray(body, min(body + size, bytes.size()) - 1)
			if bits == 8:
				for i in range(data.size()):
					data[i] = (data[i] + 128) & 0xFF  # unsigned in the file, signed in Godot
			sample.data = data
			return sample
		position = body + size + (size & 1)
	return null
