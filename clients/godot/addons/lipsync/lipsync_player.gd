# LipsyncPlayer: plays a lipsyncd track on a MeshInstance's blend shapes (Godot 3.x).
#
# A track is what `lipsync render ... --format json` (or lipsyncd's Render) writes: frames at exact
# integer-microsecond times (`t_us`), each with the 52 ARKit weights (`arkit`, in the order of
# `arkit_names`). The player keys the mesh's `blend_shapes/NAME` properties, by ARKit name or
# through `mapping` ({ARKit name: the rig's blend shape name}), interpolating linearly between
# frames (the frames are not uniform: closure key frames sit between the grid frames, and linear
# interpolation keeps their values exactly at their times; docs/output-formats.md).
#
# The clock. The face shows the track at the time the listener hears:
#   - with `audio_player_path`, an AudioStreamPlayer's playback position plus the time since the
#     last mix, minus the output latency (Godot's recipe for syncing to audio);
#   - in live mode, the session's media-clock anchor: on the "unix" clock utterance time 0 plays at
#     `utterance_zero_us`, as lipsyncd's browser viewer does (docs/viewer.md); on another clock,
#     from the header's arrival;
#   - otherwise the time since play();
#   - `clock_source`, when set (a FuncRef returning microseconds), replaces all of these: for a
#     game's own clock, cut-scenes, and tests.
#
# Live mode (follow()) reads a lipsyncd session from the viewer's WebSocket
# (`lipsyncd --http-listen HOST:PORT`, ws://HOST:PORT/ws?session=NAME): binary TrackMessages
# (track_decoder.gd), frames appended as they come; a session not started yet is asked for again
# every 250 ms for `live_wait_ms`.
#
# Bad input (a file that is not a lipsyncd track, a track of another model, a mesh without the
# shape keys, no lipsyncd) is reported with push_error saying what to do, and the scene is left as
# it was: nothing is keyed until a track and a mesh agree.
#
# Porting to Godot 4 is mechanical (docs/integrations.md, "Godot"): `export` → `@export`,
# FuncRef → Callable, Pool*Array → Packed*Array, MeshInstance → MeshInstance3D, File → FileAccess,
# JSON.parse → JSON.new().parse, WebSocketClient → WebSocketPeer, OS time → Time.
extends Node

signal track_loaded(frame_count)
signal live_header(header)
signal live_ended(code, reason)
signal finished

const TrackDecoder = preload("track_decoder.gd")

export(NodePath) var mesh_path = NodePath()
export(NodePath) var audio_player_path = NodePath()
export(String, FILE, "*.json") var track_file = ""
# {ARKit name: blend shape name, [names], or null (not driven)}: overrides the names it lists;
# every other ARKit name drives the blend shape of its own name (see _bind).
export(Dictionary) var mapping = {}
# The model the track must come from ("" accepts any): a mapping made for one model's rig.
export(String) var model = ""
export(bool) var autoplay = false
# How long follow() waits for a session that has not started yet, ms.
export(int) var live_wait_ms = 10000

# A FuncRef returning the utterance time in µs; replaces the audio and wall clocks when set.
var clock_source = null

# The track: frame times (µs) and ARKit weights, frame-major.
var frame_times_us = []
var _weights = PoolRealArray()
var _names = []  # the track's ARKit names
var _bindings = []  # [[index into _names, "blend_shapes/NAME"], ...]
var _mesh = null
var _audio = null
var _playing = false
var _start_ticks_us = 0
var last_time_us = 0  # the utterance time last shown

# Live state.
var _socket = null
var _retired_socket = null
var _decoder = TrackDecoder.new()
var _live_url = ""
var _live_session = ""
var _live_start = ""
var _live_deadline_ms = 0
var _live_retry_at_ms = -1
var _live_header = null
var _live_clock_offset_us = 0  # unix µs − OS.get_ticks_usec()
var _live_zero_ticks_us = 0  # ticks at utterance time 0 (non-unix clocks)
var _live_audio_started = false
var _live_close = [1006, ""]  # the close code and reason lipsyncd sent
var live_done = false
var live_retries = 0  # times follow() asked again for a session that had not started
var live_error = ""


func _ready():
	if track_file != "" and load_track(track_file) == OK and autoplay:
		play()


# Reads a lipsyncd JSON track and binds it to the mesh. OK, or an error code after push_error;
# on error the previous track (if any) stays and the mesh is not touched.
func load_track(path):
	var file = File.new()
	var opened = file.open(path, File.READ)
	if opened != OK:
		return _fail(ERR_FILE_CANT_OPEN, "%s: cannot open the track (error %d); render one with 'lipsync render speech.lab -o %s'" % [path, opened, path.get_file()])
	var bytes = file.get_buffer(file.get_len())
	file.close()
	# The bytes are checked before they are decoded: Godot prints a "Unicode error" line for each
	# line of a file that is not UTF-8 (thousands for a WAV) before the caller could say anything.
	if bytes.size() >= 12 and bytes.subarray(0, 3).get_string_from_ascii() == "RIFF" and bytes.subarray(8, 11).get_string_from_ascii() == "WAVE":
		return _fail(ERR_INVALID_DATA, "%s: a WAV file (audio), not a track; give it to the AudioStreamPlayer (audio_player_path) and load the track 'lipsync render INPUT --format json' wrote for that speech" % path)
	if bytes.size() >= 3 and bytes[0] == 0xEF and bytes[1] == 0xBB and bytes[2] == 0xBF:
		bytes = bytes.subarray(3, bytes.size() - 1) if bytes.size() > 3 else PoolByteArray()
	var text = bytes.get_string_from_ascii()
	if text.to_utf8().size() != bytes.size():  # not plain ASCII: a NUL or a byte of 0x80 or more
		var bad = _first_byte_not_utf8(bytes)
		if bad >= 0:
			return _fail(ERR_INVALID_DATA, "%s: not a text file (byte %d is not UTF-8); a lipsyncd track is the JSON 'lipsync render INPUT --format json' writes" % [path, bad])
		text = bytes.get_string_from_utf8()
	var start = text.strip_edges()
	if not start.begins_with("{"):
		# Not JSON (Godot's parser would print an error of its own first): a phoneme file, most often.
		return _fail(ERR_PARSE_ERROR, "%s: not a lipsyncd track: not JSON (it begins '%s'); render one with 'lipsync render INPUT --format json' (a phoneme file, such as flite -psdur output or a TextGrid, is lipsyncd's input: 'lipsync render %s -o %s.json')" % [path, start.substr(0, 30).replace("\n", " "), path.get_file(), path.get_file().get_basename()])
	var parsed = JSON.parse(text)
	if parsed.error != OK:
		return _fail(ERR_PARSE_ERROR, "%s:%d: not JSON (%s); give a track written by 'lipsync render --format json'" % [path, parsed.error_line, parsed.error_string])
	return set_track(parsed.result, path)


# The offset of the first byte of `bytes` that does not belong to a UTF-8 sequence (NUL counts as
# such: a text file has none), or -1.
static func _first_byte_not_utf8(bytes):
	var i = 0
	var count = bytes.size()
	while i < count:
		var lead = bytes[i]
		var extra = 0
		if lead == 0:
			return i
		elif lead < 0x80:
			extra = 0
		elif lead >= 0xC2 and lead <= 0xDF:
			extra = 1
		elif lead >= 0xE0 and lead <= 0xEF:
			extra = 2
		elif lead >= 0xF0 and lead <= 0xF4:
			extra = 3
		else:
			return i
		if i + extra >= count:
			return i
		for k in range(1, extra + 1):
			if bytes[i + k] & 0xC0 != 0x80:
				return i
		i += extra + 1
	return -1


# Takes a parsed lipsyncd track (the JSON document as a Dictionary); `source` names it in messages.
func set_track(doc, source = "track"):
	if typeof(doc) != TYPE_DICTIONARY or doc.get("format") != "lipsync-track":
		return _fail(ERR_INVALID_DATA, "%s: not a lipsyncd track (no \"format\": \"lipsync-track\"); render one with 'lipsync render INPUT --format json'" % source)
	if int(doc.get("version", 0)) != 1:
		return _fail(ERR_INVALID_DATA, "%s: track version %s, this add-on reads version 1; update the add-on" % [source, str(doc.get("version"))])
	var track_model = str(doc.get("model", ""))
	if model != "" and track_model != model:
		return _fail(ERR_INVALID_DATA, "%s: a track of model '%s', but this LipsyncPlayer's mapping is for model '%s'; render the track with that model ('lipsync render --model ...') or change `model` and `mapping`" % [source, track_model, model])
	var names = doc.get("arkit_names")
	var frames = doc.get("frames")
	if typeof(names) != TYPE_ARRAY or names.empty():
		return _fail(ERR_INVALID_DATA, "%s: the track has no \"arkit_names\"; render it with ARKit output (lipsync render --format json)" % source)
	if typeof(frames) != TYPE_ARRAY or frames.empty():
		return _fail(ERR_INVALID_DATA, "%s: the track has no frames" % source)
	var times = []
	var weights = PoolRealArray()
	var previous = -1
	for i in range(frames.size()):
		var frame = frames[i]
		if typeof(frame) != TYPE_DICTIONARY or not frame.has("t_us") or typeof(frame.get("arkit")) != TYPE_ARRAY or frame["arkit"].size() != names.size():
			return _fail(ERR_INVALID_DATA, "%s: frame %d: needs \"t_us\" and %d \"arkit\" weights" % [source, i, names.size()])
		var t = int(frame["t_us"])
		if t <= previous:
			return _fail(ERR_INVALID_DATA, "%s: frame %d: t_us %d is not after the previous frame's %d" % [source, i, t, previous])
		previous = t
		times.append(t)
		for w in frame["arkit"]:
			weights.append(0.0 if w == null else float(w))
	return _adopt(names, times, weights, source)


# Binds `names` to the mesh and, if every check passes, makes them the player's track.
func _adopt(names, times, weights, source):
	var bound = _bind(names, source)
	if typeof(bound) == TYPE_INT:
		return bound
	_names = names
	_bindings = bound[0]
	_mesh = bound[1]
	frame_times_us = times
	_weights = weights
	emit_signal("track_loaded", times.size())
	return OK


# [[index, property], ...] and the mesh, or an error code after push_error.
#
# Which ARKit name drives which blend shape (the Blender add-on's rule too, docs/integrations.md):
# an ARKit name that `mapping` lists drives the shapes it maps it to (a name, an array of names, or
# null: none); every other ARKit name drives the blend shape of its own name, or, failing that, the
# one shape whose name matches it but for case (`JawOpen`), and nothing where the mesh has neither.
# A mapping that names an ARKit name the track lacks, a shape the mesh lacks, or makes two ARKit
# names drive one shape is refused.
func _bind(names, source):
	var mesh_instance = get_node_or_null(mesh_path) if not mesh_path.is_empty() else null
	if not (mesh_instance is MeshInstance):
		return _fail(ERR_UNCONFIGURED, "mesh_path '%s' is not a MeshInstance; point it at the face's MeshInstance" % str(mesh_path))
	var shapes = []
	var by_lowercase = {}  # lowercase name -> the shapes of that name
	var mesh = mesh_instance.mesh
	if mesh is ArrayMesh:
		for i in range(mesh.get_blend_shape_count()):
			var shape_name = str(mesh.get_blend_shape_name(i))
			shapes.append(shape_name)
			if not by_lowercase.has(shape_name.to_lower()):
				by_lowercase[shape_name.to_lower()] = []
			by_lowercase[shape_name.to_lower()].append(shape_name)
	var targets = {}  # ARKit name -> the shapes `mapping` names for it
	var unknown = []
	var missing = []
	for arkit_name in mapping:
		var value = mapping[arkit_name]
		var listed = [value] if typeof(value) == TYPE_STRING else (value if typeof(value) == TYPE_ARRAY else [])
		var usable = typeof(value) == TYPE_NIL or not listed.empty()
		for shape in listed:
			usable = usable and typeof(shape) == TYPE_STRING and shape != ""
		if not usable:
			return _fail(ERR_INVALID_DATA, "%s: `mapping`['%s'] is %s; give a blend shape name, an array of names, or null (not driven)" % [source, str(arkit_name), JSON.print(value)])
		if names.find(arkit_name) < 0:
			unknown.append(arkit_name)
		for shape in listed:
			if not shapes.has(shape) and not missing.has(shape):
				missing.append(shape)
		targets[arkit_name] = listed
	if not unknown.empty():
		return _fail(ERR_INVALID_DATA, "%s: `mapping` names %s, which the track does not have (it has the ARKit names %s...); fix the mapping's keys" % [source, str(unknown), str(names.slice(0, 4))])
	if not missing.empty():
		return _fail(ERR_DOES_NOT_EXIST, "%s: the mesh of '%s' has no blend shapes %s that `mapping` names (it has %s); fix the mapping's values or add the shape keys" % [source, mesh_instance.name, str(missing), str(shapes)])
	var bindings = []
	var driven = {}  # blend shape -> the ARKit name driving it
	for index in range(names.size()):
		var arkit_name = names[index]
		var own = []
		if targets.has(arkit_name):
			own = targets[arkit_name]
		elif shapes.has(arkit_name):
			own = [arkit_name]
		elif by_lowercase.get(str(arkit_name).to_lower(), []).size() == 1:
			own = by_lowercase[str(arkit_name).to_lower()]
		for shape in own:
			if driven.has(shape):
				return _fail(ERR_INVALID_DATA, "%s: blend shape '%s' would be driven by both '%s' and '%s'; map one of them elsewhere or to null in `mapping`" % [source, shape, driven[shape], arkit_name])
			driven[shape] = arkit_name
			bindings.append([index, "blend_shapes/" + shape])
	if bindings.empty():
		return _fail(ERR_DOES_NOT_EXIST, "%s: the mesh of '%s' has none of the blend shapes to animate (it has %s); give it ARKit-named shape keys (jawOpen, mouthClose, ...) or set `mapping` to {ARKit name: your shape name}" % [source, mesh_instance.name, str(shapes)])
	return [bindings, mesh_instance]


func _fail(code, message):
	push_error("LipsyncPlayer: " + message)
	return code


# Starts playing at utterance time `from_us` (the audio player too, if one is set).
func play(from_us = 0):
	if frame_times_us.empty():
		push_error("LipsyncPlayer: play(): no track; call load_track() or set track_file first")
		return ERR_UNCONFIGURED
	_audio = get_node_or_null(audio_player_path) if not audio_player_path.is_empty() else null
	if _audio != null and not (_audio is AudioStreamPlayer):
		push_error("LipsyncPlayer: audio_player_path '%s' is not an AudioStreamPlayer" % str(audio_player_path))
		_audio = null
		return ERR_UNCONFIGURED
	if _audio != null:
		_audio.play(from_us / 1000000.0)
	_start_ticks_us = OS.get_ticks_usec() - from_us
	_playing = true
	show_at(from_us)
	return OK


func stop():
	_playing = false
	if _audio != null:
		_audio.stop()


func is_playing():
	return _playing


# The utterance time now, µs, from the clock in use (see the top of the file).
func current_time_us():
	if clock_source != null:
		return int(clock_source.call_func())
	if _live_header != null:
		if _live_header["clock"] == "unix":
			return OS.get_ticks_usec() + _live_clock_offset_us - int(_live_header["utterance_zero_us"])
		return OS.get_ticks_usec() - _live_zero_ticks_us
	if _audio != null:
		return audio_clock_us(_audio)
	return OS.get_ticks_usec() - _start_ticks_us


# What the listener hears now of `player`'s stream, µs: Godot's audio-sync recipe (playback position
# plus the time since the last mix, minus the output latency). The mixer runs on a thread of its own
# and moves the position and the time of the last mix one after the other, so a read that straddles
# a mix could pair the old position with the new time, or the reverse: one mix buffer (about 12 ms)
# off. The two are read until no mix came between: the time since the last mix did not restart and
# the position did not move.
static func audio_clock_us(player):
	if not player.playing or player.stream_paused:
		return int(round(player.get_playback_position() * 1000000.0))
	var seconds = 0.0
	for _attempt in range(16):
		var since_before = AudioServer.get_time_since_last_mix()
		var position = player.get_playback_position()
		var since = AudioServer.get_time_since_last_mix()
		seconds = position + since - AudioServer.get_output_latency()
		if since >= since_before and player.get_playback_position() == position:
			break
	return int(round(seconds * 1000000.0))


func _process(_delta):
	_retired_socket = null
	if _socket != null or _live_retry_at_ms >= 0:
		_poll_live()
	if _playing or _live_header != null:
		var t = current_time_us()
		show_at(t)
		# In live mode the audio (if any) starts when utterance time 0 comes, at the anchor's time.
		if _live_header != null and _audio is AudioStreamPlayer and not _live_audio_started and t >= 0:
			_audio.play(t / 1000000.0)
			_live_audio_started = true
		if _playing and clock_source == null and _audio != null and not _audio.playing:
			_playing = false  # the audio ended
			emit_signal("finished")
		elif _playing and clock_source == null and _audio == null and t > frame_times_us.back():
			_playing = false
			emit_signal("finished")


# The weight of ARKit channel `index` at `t_us`: linear between the frames around it, the first
# frame's before it, the last frame's after it.
func weight_at(index, t_us):
	var count = _names.size()
	var next = frame_times_us.bsearch(t_us, false)  # first frame after t_us
	if next == 0:
		return _weights[index]
	if next >= frame_times_us.size():
		return _weights[(frame_times_us.size() - 1) * count + index]
	var t0 = frame_times_us[next - 1]
	var t1 = frame_times_us[next]
	var w0 = _weights[(next - 1) * count + index]
	if t_us == t0:
		return w0
	var w1 = _weights[next * count + index]
	return w0 + (w1 - w0) * float(t_us - t0) / float(t1 - t0)


# Keys the mesh with the track at utterance time `t_us`.
func show_at(t_us):
	if frame_times_us.empty() or _mesh == null:
		return
	last_time_us = t_us
	for binding in _bindings:
		_mesh.set(binding[1], weight_at(binding[0], t_us))


# The ARKit names of the track and the blend shape each drives ({ARKit name: "blend_shapes/X"}).
func bound_shapes():
	var out = {}
	for binding in _bindings:
		out[_names[binding[0]]] = binding[1]
	return out


# Follows lipsyncd session `session` from its viewer at `url` ("ws://HOST:PORT", or the
# "http://HOST:PORT/view" it prints); `start` is "beginning" (what the server still holds, then
# live) or "now". Errors go to push_error (and `live_error`); OK when the connection is under way.
func follow(url, session, start = "beginning"):
	if session == "":
		return _fail(ERR_INVALID_PARAMETER, "follow(): no session name; give the name the producer streams to (lipsync stream --session NAME)")
	var base = url.strip_edges()
	if base.begins_with("http://"):
		base = "ws://" + base.substr(7)
	var cut = base.find("/", 5)
	if cut >= 0:
		base = base.substr(0, cut)
	if not base.begins_with("ws://"):
		return _fail(ERR_INVALID_PARAMETER, "follow(): '%s' is not the viewer's address; give the http://HOST:PORT/view address lipsyncd prints at start ('lipsyncd viewer on http://...', with --http-listen HOST:PORT), or ws://HOST:PORT" % url)
	_live_url = base + "/ws?session=" + session.percent_encode() + ("&start=now" if start == "now" else "")
	_live_session = session
	_live_start = start
	_live_deadline_ms = OS.get_ticks_msec() + live_wait_ms
	_live_header = null
	live_done = false
	live_error = ""
	live_retries = 0
	_live_audio_started = false
	frame_times_us = []
	_weights = PoolRealArray()
	return _connect_live()


func _connect_live():
	_live_retry_at_ms = -1
	_live_close = [1006, "the connection was lost"]
	_socket = WebSocketClient.new()
	_socket.connect("connection_error", self, "_on_socket_error")
	_socket.connect("server_close_request", self, "_on_socket_close_request")
	_socket.connect("connection_closed", self, "_on_socket_closed")
	_socket.connect("data_received", self, "_on_socket_data")
	var error = _socket.connect_to_url(_live_url)
	if error != OK:
		_socket = null
		return _live_fail(error, "cannot connect to %s (error %d); start lipsyncd with --http-listen HOST:PORT and follow the http://HOST:PORT/view address it prints" % [_live_url, error])
	return OK


func _live_fail(code, message):
	live_error = message
	_close_socket()
	return _fail(code, "live session '%s': %s" % [_live_session, message])


func _close_socket():
	if _socket != null:
		var socket = _socket
		_retire_socket()
		socket.disconnect_from_host()


# Drops the socket, kept alive until the next frame: it may be emitting the signal we are in.
func _retire_socket():
	_retired_socket = _socket
	_socket = null


func _poll_live():
	if _live_retry_at_ms >= 0:
		if OS.get_ticks_msec() >= _live_retry_at_ms:
			_connect_live()
		return
	_socket.poll()  # emits the signals below


func _on_socket_error():
	_retire_socket()
	if _live_header == null:
		_live_fail(ERR_CANT_CONNECT, "no lipsyncd viewer answered at %s; start lipsyncd with --http-listen HOST:PORT and follow the http://HOST:PORT/view address it prints" % _live_url)
	elif not live_done:
		_end_live(1006, "the connection was lost")


func _on_socket_close_request(code, reason):
	_live_close = [code, reason]


func _on_socket_closed(_was_clean):
	if _socket == null:
		return  # closed by us
	_retire_socket()
	if live_done or _live_retry_at_ms >= 0 or live_error != "":
		return
	if _live_header == null:
		_live_fail(ERR_CONNECTION_ERROR, "lipsyncd closed the connection (%d %s) before the session's header" % _live_close)
	else:
		_end_live(_live_close[0], _live_close[1])


func _on_socket_data():
	if _socket == null:
		return
	var peer = _socket.get_peer(1)
	while _socket != null and peer.get_available_packet_count() > 0:
		var packet = peer.get_packet()
		if peer.was_string_packet():
			_on_live_error_text(packet.get_string_from_utf8())
		else:
			_on_live_message(packet)


# lipsyncd's error text {"code", "message"} (then a close with 4000 + the gRPC code).
func _on_live_error_text(text):
	var parsed = JSON.parse(text)
	var code = ""
	var message = text
	if parsed.error == OK and typeof(parsed.result) == TYPE_DICTIONARY:
		code = str(parsed.result.get("code", ""))
		message = str(parsed.result.get("message", text))
	if code == "NOT_FOUND" and _live_header == null and OS.get_ticks_msec() < _live_deadline_ms:
		_close_socket()
		_live_retry_at_ms = OS.get_ticks_msec() + 250  # the session has not started yet
		live_retries += 1
		return
	if code == "NOT_FOUND":
		_live_fail(ERR_DOES_NOT_EXIST, "%s (waited %d ms); start the producer (lipsync stream INPUT --session %s) or check the name" % [message, live_wait_ms, _live_session])
	else:
		_live_fail(ERR_CANT_ACQUIRE_RESOURCE, "lipsyncd refused: %s %s" % [code, message])


func _on_live_message(bytes):
	var message = _decoder.decode_track_message(bytes)
	if _decoder.error != "":
		_live_fail(ERR_PARSE_ERROR, "a message from %s is not a lipsync.v1.TrackMessage (%s)" % [_live_url, _decoder.error])
		return
	if message.has("header"):
		var header = message["header"]
		if model != "" and header["model"] != model:
			_live_fail(ERR_INVALID_DATA, "a session of model '%s', but this LipsyncPlayer's mapping is for model '%s'; start the producer with that model or change `model` and `mapping`" % [header["model"], model])
			return
		if header["arkit_names"].empty():
			_live_fail(ERR_INVALID_DATA, "the session carries no ARKit weights; start the producer with the ARKit output on")
			return
		var bound = _bind(header["arkit_names"], "live session '%s'" % _live_session)
		if typeof(bound) == TYPE_INT:
			live_error = "the mesh does not match the session"
			_close_socket()
			return
		_names = header["arkit_names"]
		_bindings = bound[0]
		_mesh = bound[1]
		_live_clock_offset_us = OS.get_system_time_msecs() * 1000 - OS.get_ticks_usec()
		_live_zero_ticks_us = OS.get_ticks_usec()
		_audio = get_node_or_null(audio_player_path) if not audio_player_path.is_empty() else null
		_live_header = header
		emit_signal("live_header", header)
	elif message.has("frames"):
		if _live_header == null:
			_live_fail(ERR_INVALID_DATA, "frames before the header")
			return
		var batch = message["frames"]
		var count = _names.size()
		if batch["arkit"].size() != batch["t_us"].size() * count:
			_live_fail(ERR_INVALID_DATA, "a batch of %d frames with %d ARKit weights (expected %d each)" % [batch["t_us"].size(), batch["arkit"].size(), count])
			return
		frame_times_us += batch["t_us"]
		_weights.append_array(batch["arkit"])
	elif message.has("summary"):
		_end_live(1000, "OK")


func _end_live(code, reason):
	live_done = true
	_close_socket()
	emit_signal("live_ended", code, reason)
