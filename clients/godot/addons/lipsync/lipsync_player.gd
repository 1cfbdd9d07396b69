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
#   - with a voice (listen()), the AudioStreamPlayer's clock as above once it plays: the frames are
#     for the stream's own sample times;
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
# Live mode with a voice (listen()) makes the session itself: the AudioStreamPlayer at
# `audio_player_path` plays its AudioStreamSample (a WAV, 8- or 16-bit PCM) and the node sends the
# stream's own samples, as 16-bit PCM pieces of 20 ms, to the viewer's WebSocket /listen
# (ws://HOST:PORT/listen?session=NAME&rate=HZ, docs/viewer.md) as the playback position passes
# them, `listen_ahead_ms` ahead of it (lipsyncd refuses audio more than 2 s ahead of real time),
# then {"end": true}; it follows the session on /ws as above and draws its frames on the audio
# clock. listen() starts the stream; once the mixer has played its first samples the WebSocket is
# opened with the session's anchor (utterance_zero_us): the unix time at which the audio clock was
# 0, i.e. when the first sample was heard. Godot 3 gives scripts no samples of
# Ogg Vorbis or MP3 streams, nor of the microphone as it records (AudioEffectCapture is Godot
# 3.3+/4.x): those are refused with what to do (docs/integrations.md).
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
signal listen_ended(summary)  # lipsyncd's summary of the voice: {session, frames, duration_us, notes}

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
# listen(): how far ahead of the audio clock the voice is sent, ms (lipsyncd allows 2000). With
# the default budget, frames then come about 130 ms before they are heard (at 200 ms, 30 ms: often
# too late for the next frame to interpolate toward; docs/integrations.md).
export(int) var listen_ahead_ms = 300
# listen(): the latency budget asked of lipsyncd (Listen's latency_ms, 100 to 2000).
export(int) var listen_latency_ms = 200

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
var _live_retry_ms = 250  # how soon a session not started yet is asked for again
var _live_header = null
var _live_clock_offset_us = 0  # unix µs − OS.get_ticks_usec()
var _live_zero_ticks_us = 0  # ticks at utterance time 0 (non-unix clocks)
var _live_audio_started = false
var _live_close = [1006, ""]  # the close code and reason lipsyncd sent
var live_done = false
var live_retries = 0  # times follow() asked again for a session that had not started
var live_error = ""

# The voice (listen()) state.
const VOICE_PIECE_MS = 20  # a piece of the voice, as the viewer page sends them
const VOICE_LOG_MAX = 100000  # pieces kept in listen_pieces (half an hour)
var _voice_socket = null
var _retired_voice_socket = null
var _voice_url = ""
var _voice_session = ""
var _voice_base = ""  # ws://HOST:PORT of the viewer
var _voice_pcm = PoolByteArray()  # the stream's samples, as they are stored (8- or 16-bit)
var _voice_format = 0
var _voice_rate = 0
var _voice_channels = 1
var _voice_frames = 0  # sample frames in the stream
var _voice_sent_frames = 0
var _voice_query = ""  # /listen's parameters but the anchor
var _voice_unix_offset_us = 0  # unix µs − OS.get_ticks_usec()
var _voice_last_us = 0  # the audio clock last read while it played
var _voice_open = false  # the WebSocket is open
var _voice_close = [1006, ""]
var listening = false  # a voice is being sent
var listen_error = ""
var listen_summary = null
var listen_sent_bytes = 0
var listen_max_ahead_us = 0  # the furthest the samples sent ran ahead of the audio clock
var listen_pieces = []  # [audio time µs at a piece's end, OS.get_ticks_usec() when it was sent]


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
	_leave_voice()
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
	if _voice_session != "":
		return _voice_time_us()
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
	_retired_voice_socket = null
	if _socket != null or _live_retry_at_ms >= 0:
		_poll_live()
	if _voice_session != "":
		_step_voice()
	if _playing or _live_header != null:
		var t = current_time_us()
		show_at(t)
		# In live mode the audio (if any) starts when utterance time 0 comes, at the anchor's time.
		if _live_header != null and _voice_session == "" and _audio is AudioStreamPlayer and not _live_audio_started and t >= 0:
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
	var base = _viewer_base(url, "follow()")
	if base == "":
		return ERR_INVALID_PARAMETER
	_leave_voice()
	return _follow(base, session, start)


# follow() of a viewer at `base` (ws://HOST:PORT), also the voice's own follower.
func _follow(base, session, start = "beginning"):
	_close_socket()
	_live_url = base + "/ws?session=" + session.percent_encode() + ("&start=now" if start == "now" else "")
	_live_session = session
	_live_start = start
	_live_deadline_ms = OS.get_ticks_msec() + live_wait_ms
	_live_retry_ms = 250
	_live_header = null
	live_done = false
	live_error = ""
	live_retries = 0
	_live_audio_started = false
	frame_times_us = []
	_weights = PoolRealArray()
	return _connect_live()


# ws://HOST:PORT of the viewer at `url` (as follow() takes it), or "" after push_error.
func _viewer_base(url, caller):
	var base = url.strip_edges()
	if base.begins_with("http://"):
		base = "ws://" + base.substr(7)
	var cut = base.find("/", 5)
	if cut >= 0:
		base = base.substr(0, cut)
	if not base.begins_with("ws://"):
		_fail(ERR_INVALID_PARAMETER, "%s: '%s' is not the viewer's address; give the http://HOST:PORT/view address lipsyncd prints at start ('lipsyncd viewer on http://...', with --http-listen HOST:PORT), or ws://HOST:PORT" % [caller, url])
		return ""
	return base


func _connect_live():
	_live_retry_at_ms = -1
	_live_close = [1006, "the connection was lost"]
	_socket = _open_socket(_live_url, {"connection_error": "_on_socket_error", "server_close_request": "_on_socket_close_request", "connection_closed": "_on_socket_closed", "data_received": "_on_socket_data"})
	var error = _socket.get_meta("connect_error")
	if error != OK:
		_socket = null
		return _live_fail(error, "cannot connect to %s (error %d); start lipsyncd with --http-listen HOST:PORT and follow the http://HOST:PORT/view address it prints" % [_live_url, error])
	return OK


# A WebSocketClient connecting to `url`, its signals calling this node's `handlers` ({signal:
# method}); connect_to_url's error is its meta "connect_error".
func _open_socket(url, handlers):
	var socket = WebSocketClient.new()
	for signal_name in handlers:
		socket.connect(signal_name, self, handlers[signal_name])
	socket.set_meta("connect_error", socket.connect_to_url(url))
	return socket


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
		_live_retry_at_ms = OS.get_ticks_msec() + _live_retry_ms  # the session has not started yet
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


# --- Live mode with a voice: listen() -------------------------------------------------------------

# Makes the face speak what the AudioStreamPlayer at `audio_player_path` plays: starts its stream,
# sends its samples to lipsyncd's viewer at `url` (as follow() takes it) as they play, into
# session `session`, and follows that session. `transcript`: the words said
# (optional; the /p b m/ closures are far more reliable with them). OK when under way; an error
# code after push_error when the player's stream cannot be sent (nothing is sent then). Later
# errors (lipsyncd's refusal, a lost connection) go to push_error and `listen_error`.
func listen(url, session, transcript = ""):
	var audio = get_node_or_null(audio_player_path) if not audio_player_path.is_empty() else null
	if not (audio is AudioStreamPlayer):
		return _fail(ERR_UNCONFIGURED, "listen(): audio_player_path '%s' is not an AudioStreamPlayer; point it at the AudioStreamPlayer that plays the voice" % str(audio_player_path))
	var stream = audio.stream
	var who = "the AudioStreamPlayer '%s'" % audio.name
	if stream == null:
		return _fail(ERR_UNCONFIGURED, "listen(): %s has no stream; give it the voice to speak (a WAV, imported as an AudioStreamSample)" % who)
	if not (stream is AudioStreamSample):
		return _fail(ERR_UNAVAILABLE, "listen(): %s plays an %s, whose samples Godot 3 does not give to scripts; import the voice as a WAV (AudioStreamSample, 8- or 16-bit PCM), or render its track offline ('lipsync render voice.wav --text \"...\" --format json') and play() it" % [who, stream.get_class()])
	if stream.format == AudioStreamSample.FORMAT_IMA_ADPCM:
		return _fail(ERR_UNAVAILABLE, "listen(): %s plays an IMA-ADPCM WAV, whose samples the add-on does not decode; reimport the WAV with Compress Mode 'Disabled' (the Import dock) so that it is 16-bit PCM" % who)
	var channels = 2 if stream.stereo else 1
	var bytes_per_frame = (2 if stream.format == AudioStreamSample.FORMAT_16_BITS else 1) * channels
	var data = stream.data
	if data.size() < bytes_per_frame:
		return _fail(ERR_INVALID_DATA, "listen(): %s has an AudioStreamSample without samples; give it the voice's WAV" % who)
	if session == "":
		return _fail(ERR_INVALID_PARAMETER, "listen(): no session name; give the name the face's session takes (followers watch it by that name)")
	var base = _viewer_base(url, "listen()")
	if base == "":
		return ERR_INVALID_PARAMETER
	_end_voice_socket()
	_close_socket()  # a session followed before
	_live_retry_at_ms = -1
	_live_header = null
	_audio = audio
	_voice_pcm = data
	_voice_format = stream.format
	_voice_rate = stream.mix_rate
	_voice_channels = channels
	_voice_frames = data.size() / bytes_per_frame
	_voice_sent_frames = 0
	_voice_session = session
	_voice_base = base
	_voice_unix_offset_us = OS.get_system_time_msecs() * 1000 - OS.get_ticks_usec()
	_voice_last_us = 0
	_voice_open = false
	_voice_close = [1006, "the connection was lost"]
	listening = true
	listen_error = ""
	listen_summary = null
	listen_sent_bytes = 0
	listen_max_ahead_us = 0
	listen_pieces = []
	_voice_query = "session=%s&rate=%d&channels=%d&latency_ms=%d" % [session.percent_encode(), _voice_rate, channels, listen_latency_ms]
	if transcript != "":
		_voice_query += "&transcript=" + transcript.percent_encode()
	_voice_url = ""
	_audio.play(0)
	return OK


# Opens the voice's WebSocket, anchored where the audio clock says sample 0 was heard.
func _connect_voice():
	var zero_unix_us = OS.get_ticks_usec() + _voice_unix_offset_us - audio_clock_us(_audio)
	_voice_url = _voice_base + "/listen?" + _voice_query + "&utterance_zero_us=%d" % zero_unix_us
	_voice_socket = _open_socket(_voice_url, {"connection_established": "_on_voice_connected", "connection_error": "_on_voice_socket_error", "server_close_request": "_on_voice_close_request", "connection_closed": "_on_voice_closed", "data_received": "_on_voice_data"})
	var error = _voice_socket.get_meta("connect_error")
	if error != OK:
		_voice_socket = null
		return _voice_fail(error, "cannot connect to %s (error %d); start lipsyncd with --http-listen HOST:PORT and give the http://HOST:PORT/view address it prints" % [_voice_base, error])
	return OK


# `frames` 16-bit little-endian PCM frames from `from_frame` of an AudioStreamSample's `data`, stored
# in `format` (8- or 16-bit) with `channels` interleaved: 16-bit data is that already; Godot keeps
# 8-bit samples signed, so each becomes a 16-bit value with it as the high byte (s × 256).
static func pcm16_of(data, format, channels, from_frame, frames):
	if format == AudioStreamSample.FORMAT_16_BITS:
		return data.subarray(from_frame * 2 * channels, (from_frame + frames) * 2 * channels - 1)
	var first = from_frame * channels
	var count = frames * channels
	var out = PoolByteArray()
	out.resize(count * 2)
	for i in range(count):
		out[2 * i] = 0
		out[2 * i + 1] = data[first + i]
	return out


# The voice's utterance time, µs: the audio clock; after the audio stopped, where it stopped.
func _voice_time_us():
	if _audio != null and _audio.playing:
		_voice_last_us = audio_clock_us(_audio)
	return _voice_last_us


# Each frame while a voice is under way: connects once the audio has played (the anchor), sends
# the samples the playback position (plus listen_ahead_ms) has reached in pieces of
# VOICE_PIECE_MS, and ends the voice ({"end": true}) once all are sent or the audio stopped.
func _step_voice():
	if _voice_socket != null:
		_voice_socket.poll()  # emits the _on_voice_* signals
	elif listening and _voice_url == "" and (_audio.get_playback_position() > 0.0 or not _audio.playing):
		_connect_voice()
	if not listening or not _voice_open or _voice_socket == null:
		return
	var stopped = not _audio.playing  # the stream ended, or stop() was called
	var now_us = _voice_time_us()
	var due = min(_voice_frames, (now_us + listen_ahead_ms * 1000) * _voice_rate / 1000000)
	var piece_frames = max(1, _voice_rate * VOICE_PIECE_MS / 1000)
	var peer = _voice_socket.get_peer(1)
	peer.set_write_mode(WebSocketPeer.WRITE_MODE_BINARY)
	while _voice_sent_frames < due:
		var frames = min(piece_frames, due - _voice_sent_frames)
		if frames < piece_frames and _voice_sent_frames + frames < _voice_frames and not stopped:
			break  # whole pieces only, but for the stream's last
		var piece = pcm16_of(_voice_pcm, _voice_format, _voice_channels, _voice_sent_frames, frames)
		if peer.put_packet(piece) != OK:
			break  # the socket's output buffer is full: the rest next frame
		_voice_sent_frames += frames
		listen_sent_bytes += piece.size()
		if listen_pieces.size() < VOICE_LOG_MAX:
			listen_pieces.append([_voice_sent_frames * 1000000 / _voice_rate, OS.get_ticks_usec()])
	listen_max_ahead_us = max(listen_max_ahead_us, _voice_sent_frames * 1000000 / _voice_rate - now_us)
	if _voice_sent_frames >= _voice_frames or stopped:
		peer.set_write_mode(WebSocketPeer.WRITE_MODE_TEXT)
		peer.put_packet(JSON.print({"end": true}).to_utf8())
		listening = false


# Leaves the voice's clock for play() or follow(); a voice still being sent is cut off there (its
# session's followers see it end as ABORTED).
func _leave_voice():
	_end_voice_socket()
	listening = false
	_voice_session = ""


func _voice_fail(code, message):
	listen_error = message
	listening = false
	_end_voice_socket()
	if _live_header == null:  # the session will not start: stop waiting for it
		_close_socket()
		_live_retry_at_ms = -1
	return _fail(code, "listen(): session '%s': %s" % [_voice_session, message])


# Closes the voice's WebSocket, kept alive until the next frame (it may be emitting the signal we are in).
func _end_voice_socket():
	_voice_open = false
	if _voice_socket != null:
		var socket = _voice_socket
		_retired_voice_socket = socket
		_voice_socket = null
		socket.disconnect_from_host()


func _on_voice_connected(_protocol):
	_voice_open = true
	_follow(_voice_base, _voice_session)  # the session's frames, as any follower gets them
	_live_retry_ms = 20  # lipsyncd is opening the session now: its first frames are due soon


func _on_voice_socket_error():
	_retired_voice_socket = _voice_socket
	_voice_socket = null
	if listen_error == "" and listen_summary == null:
		_voice_fail(ERR_CANT_CONNECT, "no lipsyncd viewer answered at %s; start lipsyncd with --http-listen HOST:PORT and give the http://HOST:PORT/view address it prints" % _voice_base)


func _on_voice_close_request(code, reason):
	_voice_close = [code, reason]


func _on_voice_closed(_was_clean):
	if _voice_socket == null:
		return  # closed by us
	_retired_voice_socket = _voice_socket
	_voice_socket = null
	_voice_open = false
	if listen_error == "" and listen_summary == null:
		_voice_fail(ERR_CONNECTION_ERROR, "lipsyncd closed the voice's WebSocket (%d %s) before its summary" % _voice_close)


# lipsyncd's text on /listen: its refusal {"code", "message"} (then a close with 4000 + the gRPC
# code), or after {"end": true} the voice's summary {"session", "frames", "duration_us", "notes"}.
func _on_voice_data():
	while _voice_socket != null and _voice_socket.get_peer(1).get_available_packet_count() > 0:
		var text = _voice_socket.get_peer(1).get_packet().get_string_from_utf8()
		var parsed = JSON.parse(text)
		var doc = parsed.result if parsed.error == OK else null
		if typeof(doc) != TYPE_DICTIONARY:
			_voice_fail(ERR_PARSE_ERROR, "lipsyncd answered '%s', not JSON" % text.substr(0, 80))
		elif doc.has("code"):
			_voice_fail(ERR_CANT_ACQUIRE_RESOURCE, "lipsyncd refused the voice: %s: %s" % [str(doc["code"]), str(doc.get("message", ""))])
		else:
			listen_summary = doc
			emit_signal("listen_ended", doc)
