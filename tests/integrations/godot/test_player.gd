# LipsyncPlayer inside real Godot (godot3-server), one behaviour per LIPSYNC_GODOT_TEST:
#
#   closures   tracks of real speech (LIPSYNC_TRACKS: lipsync render output of tests/data/closures)
#              played through an injected clock: at every closure key frame and every open-vowel
#              frame the mesh's blend shapes equal the track's ARKit weights, between frames they
#              are the linear interpolation, and the closure conventions of docs/output-formats.md
#              hold on the mesh.
#   audio      the AudioStreamPlayer's clock drives the face: the player's time is the playback
#              position + time since the last mix − output latency; pausing the audio freezes the
#              face, seeking it moves the face, its end ends the playback.
#   bad_input  a track of another model, a mesh without the shape keys, a mapping to missing shapes,
#              a mapping that drives one shape from two names, a file that is not a track (a viseme
#              file, a phoneme file, a WAV, bytes that are not UTF-8): an error code (push_error says what to do, the
#              harness reads stderr) and the scene as it was. A track with a byte order mark and
#              non-ASCII text loads.
#   mapping    the one rule for names (the Blender add-on's too): a partial mapping overrides the
#              ARKit names it lists (a shape, several, or null: none) and every other ARKit name
#              drives the blend shape of its own name (or the one that matches it but for case).
#
# Prints "ok: ..." per check passed and "FAIL: ..." per failure; exits 0 only when all passed.
extends "res://checking_tree.gd"

const Fixture = preload("res://face_fixture.gd")
const LipsyncPlayer = preload("res://addons/lipsync/lipsync_player.gd")
const TOLERANCE = 1e-6  # float32 weights through float64 JSON and back
const MIX_BUFFER_FRAMES = 512  # what the Dummy audio driver mixes at a time (about 12 ms)

var step = 0
var clock_us = 0
var started_ms = 0
var state = {}


func _init():
	mode = OS.get_environment("LIPSYNC_GODOT_TEST")
	started_ms = OS.get_ticks_msec()
	if mode == "closures":
		_setup_closures()
	elif mode == "audio":
		_setup_audio()
	elif mode == "bad_input":
		_run_bad_input()
		_finish()
	elif mode == "mapping":
		_run_mapping()
		_finish()
	else:
		_fail("unknown LIPSYNC_GODOT_TEST '%s'" % mode)
		_finish()


func _idle(_delta):
	if OS.get_ticks_msec() - started_ms > 30000:
		_fail("timed out at step %d" % step)
		_finish()
		return false
	if mode == "closures":
		_step_closures()
	elif mode == "audio":
		_step_audio()
	return false


func _clock():
	return clock_us


func _arkit_names():
	var names = []
	var doc = Fixture.read_json(OS.get_environment("LIPSYNC_TRACKS").split(";")[0])
	for name in doc["arkit_names"]:
		names.append(name)
	return names


func _new_player(face, doc_path):
	var player = LipsyncPlayer.new()
	player.name = "Lipsync"
	get_root().add_child(player)
	player.mesh_path = player.get_path_to(face)
	if doc_path != "":
		_check(player.load_track(doc_path) == OK, "%s loads" % doc_path)
	return player


# --- closures: the injected clock steps through the times to check, one per frame ------------

func _setup_closures():
	var paths = OS.get_environment("LIPSYNC_TRACKS").split(";")
	var face = Fixture.make_face(_arkit_names())
	get_root().add_child(face)
	state["face"] = face
	state["player"] = _new_player(face, "")
	state["player"].clock_source = funcref(self, "_clock")
	# The times to show: (track index, time, expected {name: weight}, what).
	var checks = []
	state["docs"] = []
	for path in paths:
		var doc = Fixture.read_json(path)
		state["docs"].append(doc)
		var names = doc["arkit_names"]
		var jaw = names.find("jawOpen")
		var frames = doc["frames"]
		for i in range(frames.size()):
			var frame = frames[i]
			var kind = frame["kind"]
			var open_vowel = frame["arkit"][jaw] >= 0.25 and (i == 0 or frame["arkit"][jaw] >= frames[i - 1]["arkit"][jaw]) and (i + 1 == frames.size() or frame["arkit"][jaw] >= frames[i + 1]["arkit"][jaw])
			if kind == "closure_start" or kind == "closure_end" or open_vowel:
				checks.append([path, int(frame["t_us"]), _weights_of(names, frame["arkit"]), kind if kind != "uniform" and kind != "short_segment" else "open vowel"])
			if i + 1 < frames.size() and i % 7 == 3:
				# Between two frames: the linear interpolation, written out here.
				var t0 = int(frame["t_us"])
				var t1 = int(frames[i + 1]["t_us"])
				var t = t0 + (t1 - t0) / 3
				var between = {}
				for n in range(names.size()):
					var w0 = float(frame["arkit"][n])
					var w1 = float(frames[i + 1]["arkit"][n])
					between[names[n]] = w0 + (w1 - w0) * float(t - t0) / float(t1 - t0)
				checks.append([path, t, between, "between frames"])
	state["checks"] = checks
	state["loaded"] = ""
	state["closures"] = 0
	state["open_vowels"] = 0
	state["sealed_or_tucked"] = 0


func _weights_of(names, arkit):
	var out = {}
	for n in range(names.size()):
		out[names[n]] = float(arkit[n])
	return out


func _step_closures():
	var checks = state["checks"]
	var player = state["player"]
	var face = state["face"]
	if step > 0:
		# The previous step's time was shown by the player's own _process.
		var check = checks[step - 1]
		var worst = 0.0
		var worst_name = ""
		for name in check[2]:
			var shown = face.get("blend_shapes/" + name)
			var error = abs(shown - check[2][name])
			if error > worst:
				worst = error
				worst_name = name
		_check(worst <= TOLERANCE, "%s at %d us (%s): %s shows %f, the track %f" % [check[0].get_file(), check[1], check[3], worst_name, face.get("blend_shapes/" + worst_name) if worst_name != "" else 0.0, check[2].get(worst_name, 0.0)])
		_check(player.last_time_us == check[1], "the player showed %d us, the clock said %d" % [player.last_time_us, check[1]])
		if check[3] == "closure_start" or check[3] == "closure_end":
			state["closures"] += 1
			var jaw = face.get("blend_shapes/jawOpen")
			var sealed = face.get("blend_shapes/mouthClose") >= jaw - 0.02
			var tucked = face.get("blend_shapes/mouthRollLower") >= 0.3 and jaw <= 0.15
			if _check(sealed or tucked, "%s at %d us: a closure key frame neither sealed nor tucked on the mesh (jawOpen %f, mouthClose %f, mouthRollLower %f)" % [check[0].get_file(), check[1], jaw, face.get("blend_shapes/mouthClose"), face.get("blend_shapes/mouthRollLower")]):
				state["sealed_or_tucked"] += 1
		elif check[3] == "open vowel":
			state["open_vowels"] += 1
			_check(face.get("blend_shapes/jawOpen") >= 0.25, "open vowel at %d us shows jawOpen %f" % [check[1], face.get("blend_shapes/jawOpen")])
	if step >= checks.size():
		print("ok: %d closure key frames (all sealed or tucked on the mesh), %d open-vowel frames, %d points between frames, %d tracks" % [state["closures"], state["open_vowels"], checks.size() - state["closures"] - state["open_vowels"], state["docs"].size()])
		_check(state["closures"] >= 40, "closure key frames checked: %d" % state["closures"])
		_check(state["open_vowels"] >= 10, "open-vowel frames checked: %d" % state["open_vowels"])
		_finish()
		return
	var next = checks[step]
	if next[0] != state["loaded"]:
		_check(player.load_track(next[0]) == OK, "%s loads" % next[0])
		_check(player.play() == OK, "%s plays" % next[0])
		state["loaded"] = next[0]
	clock_us = next[1]
	step += 1


# --- audio: the AudioStreamPlayer's clock --------------------------------------------------------

func _setup_audio():
	var path = OS.get_environment("LIPSYNC_TRACKS").split(";")[0]
	var face = Fixture.make_face(_arkit_names())
	get_root().add_child(face)
	var doc = Fixture.read_json(path)
	var end_us = int(doc["frames"][doc["frames"].size() - 1]["t_us"])
	var audio = AudioStreamPlayer.new()
	audio.name = "Speech"
	audio.stream = Fixture.make_silence(end_us / 1000000.0 + 0.3)
	get_root().add_child(audio)
	var player = _new_player(face, path)
	player.audio_player_path = player.get_path_to(audio)
	player.connect("finished", self, "_on_finished")
	state = {"face": face, "audio": audio, "player": player, "end_us": end_us, "phase": "start",
			"samples": 0, "finished": false, "wall_start_us": 0, "paused_time": 0, "paused_at_ms": 0,
			"seek_at_ms": 0, "audio_start_us": 0, "max_clock_error_us": 0, "max_weight_error": 0.0}


func _on_finished():
	state["finished"] = true


func _step_audio():
	var player = state["player"]
	var audio = state["audio"]
	var face = state["face"]
	step += 1
	if state["phase"] == "start":
		_check(player.play() == OK, "play() starts")
		state["wall_start_us"] = OS.get_ticks_usec()
		state["phase"] = "playing"
		return
	# What the player showed in the last frame equals the track at its own time…
	var t = player.last_time_us
	for name in ["jawOpen", "mouthClose", "mouthFunnel", "mouthRollLower"]:
		var index = player._names.find(name)
		var error = abs(face.get("blend_shapes/" + name) - player.weight_at(index, t))
		state["max_weight_error"] = max(state["max_weight_error"], error)
	# …and its time is the audio clock (read again now: the time since the last mix moves on). The
	# Dummy driver mixes on a thread of its own, a buffer (about 12 ms) at a time, and may mix late
	# under load; a mix between two reads then moves the recipe's value either way, by up to a buffer.
	# So each value is checked between the two readings taken just before and just after it, in
	# whichever order they came (CI saw 58167 then 46445 us), give or take one buffer: Godot 3.2
	# moves the playback position and resets the time since the last mix at two moments, and a read
	# that falls between them (the add-on's or the recipe's) is a buffer off (CI saw 1316104 against
	# 1327955..1339328).
	var recipe_before = _recipe_us(audio)
	var audio_now = LipsyncPlayer.audio_clock_us(audio)
	var recipe_after = _recipe_us(audio)
	var buffer_us = int(1000000.0 * MIX_BUFFER_FRAMES / AudioServer.get_mix_rate())
	_check(_between(audio_now, min(recipe_before, recipe_after) - buffer_us, max(recipe_before, recipe_after) + buffer_us),
			"audio_clock_us %d, Godot's recipe %d..%d" % [audio_now, recipe_before, recipe_after])
	# The player's clock now is the audio clock now (the face shown lags it by at most a frame).
	var player_now = player.current_time_us()
	var audio_after = LipsyncPlayer.audio_clock_us(audio)
	_check(_between(player_now, audio_now, audio_after),
			"the player's clock is not the audio's: %d vs %d..%d us" % [player_now, audio_now, audio_after])
	if state["phase"] == "playing" and audio.playing:
		state["samples"] += 1
		state["max_clock_error_us"] = max(state["max_clock_error_us"], abs(t - audio_now))
		if audio_now >= 600000:
			# The Dummy driver mixes on a thread of its own: report its pace against the wall clock.
			print("ok: the audio clock ran %d us in %d us of wall time (the Dummy driver's pace: %.2fx)" % [audio_now, OS.get_ticks_usec() - state["wall_start_us"], float(audio_now) / float(OS.get_ticks_usec() - state["wall_start_us"])])
			audio.stream_paused = true
			state["phase"] = "paused"
			state["paused_at_ms"] = OS.get_ticks_msec()
			state["paused_steps"] = 0
	elif state["phase"] == "paused":
		state["paused_steps"] += 1
		# The mixer takes up to a mix (and the player a frame) to see the pause; then nothing moves.
		# On a loaded machine the mixer thread may see it later: wait until two frames agree.
		var paused_for_ms = OS.get_ticks_msec() - state["paused_at_ms"]
		if not state.has("paused_jaw") and paused_for_ms >= 100 and t == state.get("paused_previous", -1):
			state["paused_time"] = t
			state["paused_jaw"] = face.get("blend_shapes/jawOpen")
			state["paused_steps"] = 0
			state["held_since_ms"] = OS.get_ticks_msec()
		elif state.has("paused_jaw"):
			_check(t == state["paused_time"], "paused audio: the face moved from %d to %d us" % [state["paused_time"], t])
			_check(face.get("blend_shapes/jawOpen") == state["paused_jaw"], "paused audio: jawOpen changed")
		state["paused_previous"] = t
		if state.has("held_since_ms") and OS.get_ticks_msec() - state["held_since_ms"] >= 300:
			print("ok: audio paused %d ms of wall time: the face held %d us over its last 300 ms, %d frames" % [OS.get_ticks_msec() - state["paused_at_ms"], state["paused_time"], state["paused_steps"]])
			_check(state["paused_steps"] >= 3, "frames while paused: %d" % state["paused_steps"])
			audio.stream_paused = false
			audio.seek(1.2)
			state["phase"] = "seeked"
			state["seek_at_ms"] = OS.get_ticks_msec()
	elif state["phase"] == "seeked":
		# The face jumps to 1.2 s once the mixer has taken the seek, and runs on from there.
		var since_ms = OS.get_ticks_msec() - state["seek_at_ms"]
		if t >= 1150000:
			_check(t <= 1200000 + since_ms * 1000 + 50000, "after seek(1.2) and %d ms the face is at %d us" % [since_ms, t])
			print("ok: %d ms after seek(1.2 s) the face shows %d us" % [since_ms, t])
			state["phase"] = "to the end"
		elif since_ms > 3000:
			_fail("the face did not follow seek(1.2): at %d us after %d ms" % [t, since_ms])
			state["phase"] = "to the end"
	elif state["phase"] == "to the end":
		if state["finished"] or not player.is_playing():
			_check(state["finished"], "the finished signal came when the audio ended")
			_check(not audio.playing, "the audio ended")
			_check(player.last_time_us >= state["end_us"], "the face reached the track's end (%d of %d us)" % [player.last_time_us, state["end_us"]])
			_check(state["samples"] >= 10, "frames sampled while playing: %d" % state["samples"])
			# A sanity bound only: one frame of Godot's main loop, which a loaded machine stretches.
			_check(state["max_clock_error_us"] <= 250000, "the face shown was %d us behind the audio clock" % state["max_clock_error_us"])
			_check(state["max_weight_error"] <= TOLERANCE, "the face showed the track at its time (error %f)" % state["max_weight_error"])
			var wall = OS.get_ticks_usec() - state["wall_start_us"]
			print("ok: %d frames followed the audio clock (the face shown at most %d us behind it: one frame; weights exact to %s); the audio ran %d us of a %d us track in %d us of wall time (with a 400 ms pause and a seek)" % [state["samples"], state["max_clock_error_us"], state["max_weight_error"], state["end_us"], state["end_us"], wall])
			_finish()


# --- bad input: errors, and the scene as it was ---------------------------------------------------

func _run_bad_input():
	var good = OS.get_environment("LIPSYNC_TRACKS").split(";")[0]
	var other = OS.get_environment("LIPSYNC_OTHER_MODEL_TRACK")
	var face = Fixture.make_face(_arkit_names())
	get_root().add_child(face)
	var player = _new_player(face, "")
	player.model = "default"
	face.set("blend_shapes/jawOpen", 0.5)

	# A track of another model: refused, nothing keyed.
	_check(player.load_track(other) == ERR_INVALID_DATA, "a track of another model is refused")
	player.show_at(500000)
	_check(face.get("blend_shapes/jawOpen") == 0.5, "the face is untouched after a refused track")
	_check(player.frame_times_us.empty(), "no track was taken")

	# The good track loads; a refused one afterwards leaves it in place.
	_check(player.load_track(good) == OK, "the default model's track loads")
	var frames = player.frame_times_us.size()
	_check(player.load_track(other) == ERR_INVALID_DATA, "a track of another model is refused after a good one")
	_check(player.frame_times_us.size() == frames, "the good track stays")

	# Not a track at all.
	_check(player.load_track(OS.get_environment("LIPSYNC_NOT_A_TRACK")) == ERR_INVALID_DATA, "a viseme file is not a track")
	_check(player.load_track("/nonexistent/track.json") == ERR_FILE_CANT_OPEN, "a missing file is reported")
	_check(player.load_track(OS.get_environment("LIPSYNC_WAV")) == ERR_INVALID_DATA, "a WAV is not a track")
	_check(player.load_track(OS.get_environment("LIPSYNC_NOT_UTF8")) == ERR_INVALID_DATA, "bytes that are not UTF-8 are not a track")
	_check(player.load_track(OS.get_environment("LIPSYNC_PHONEMES")) == ERR_PARSE_ERROR, "a phoneme file is not a track")
	_check(player.frame_times_us.size() == frames, "the good track stays after refused files")
	# UTF-8 with a byte order mark and text beyond ASCII is a track like any other.
	_check(player.load_track(OS.get_environment("LIPSYNC_BOM_TRACK")) == OK, "a track with a byte order mark and non-ASCII text loads")
	_check(player.frame_times_us.size() == frames, "it has the good track's frames")

	# A mesh without the shape keys.
	var cube = Fixture.make_face(["Key 1", "Smile"], "Cube")
	get_root().add_child(cube)
	cube.set("blend_shapes/Smile", 0.25)
	var on_cube = _new_player(cube, "")
	_check(on_cube.load_track(good) == ERR_DOES_NOT_EXIST, "a mesh without ARKit shape keys is refused")
	on_cube.clock_source = funcref(self, "_clock")
	clock_us = 500000
	on_cube.show_at(500000)
	_check(cube.get("blend_shapes/Smile") == 0.25 and cube.get("blend_shapes/Key 1") == 0.0, "the mesh without shape keys is untouched")
	_check(on_cube.play() == ERR_UNCONFIGURED, "play() without a track is refused")

	# A mapping to shapes the mesh lacks (with and without one it has), one from names the track
	# lacks, one that is not a shape name.
	on_cube.mapping = {"jawOpen": "Smile", "mouthClose": "MouthClosed"}
	_check(on_cube.load_track(good) == ERR_DOES_NOT_EXIST, "a mapping to a missing shape is refused")
	on_cube.mapping = {"jawOpen": "MouthOpen"}
	_check(on_cube.load_track(good) == ERR_DOES_NOT_EXIST, "a mapping whose only shape is missing is refused")
	on_cube.mapping = {"jawOpenWide": "Smile"}
	_check(on_cube.load_track(good) == ERR_INVALID_DATA, "a mapping from a name the track lacks is refused")
	on_cube.mapping = {"jawOpen": 5}
	_check(on_cube.load_track(good) == ERR_INVALID_DATA, "a mapping to a number is refused")
	_check(cube.get("blend_shapes/Smile") == 0.25, "the mesh is untouched after refused mappings")
	# Two ARKit names onto one shape: jawOpen mapped to mouthClose, which mouthClose drives itself.
	var crossed = _new_player(face, "")
	crossed.mapping = {"jawOpen": "mouthClose"}
	_check(crossed.load_track(good) == ERR_INVALID_DATA, "a mapping that drives one shape from two names is refused")
	_check(face.get("blend_shapes/jawOpen") == 0.5, "the face is untouched after the refused mapping")
	# A mapping that fits animates the rig's own names.
	on_cube.mapping = {"jawOpen": "Smile"}
	_check(on_cube.load_track(good) == OK, "a mapping onto the rig's own names loads")
	on_cube.show_at(500000)
	_check(abs(cube.get("blend_shapes/Smile") - on_cube.weight_at(on_cube._names.find("jawOpen"), 500000)) <= TOLERANCE and cube.get("blend_shapes/Smile") != 0.25, "the mapped shape follows jawOpen")

	# A mesh path that is no MeshInstance.
	var lost = _new_player(face, "")
	lost.mesh_path = NodePath("/root/Nowhere")
	_check(lost.load_track(good) == ERR_UNCONFIGURED, "a mesh_path to nothing is refused")
	print("ok: bad input refused with the scene untouched")

	# The inspector's way, for contrast: properties set before the node enters the tree load and
	# play the track in _ready.
	var configured = LipsyncPlayer.new()
	configured.mesh_path = NodePath("/root/Face")
	configured.track_file = good
	configured.autoplay = true
	get_root().add_child(configured)
	_check(configured.frame_times_us.size() == frames and configured.is_playing(), "track_file and autoplay load and play in _ready")
	_check(face.get("blend_shapes/jawOpen") != 0.5, "the configured player keyed the face")
	print("ok: track_file and autoplay play on _ready")


# --- mapping: one rule for names ------------------------------------------------------------------

func _run_mapping():
	var good = OS.get_environment("LIPSYNC_TRACKS").split(";")[0]
	var names = _arkit_names()
	var face = Fixture.make_face(names + ["JawDrop", "CheekRaise_L"])
	get_root().add_child(face)
	for shape in ["jawOpen", "eyeBlinkLeft"]:
		face.set("blend_shapes/" + shape, 0.5)
	var player = _new_player(face, "")
	player.mapping = {"jawOpen": "JawDrop", "mouthSmileLeft": ["mouthSmileLeft", "CheekRaise_L"], "eyeBlinkLeft": null}
	_check(player.load_track(good) == OK, "a partial mapping loads")
	# Which shape each ARKit name drives: the mapping's for the names it lists, the own for the rest.
	var expected = {"JawDrop": "jawOpen", "CheekRaise_L": "mouthSmileLeft"}
	for name in names:
		if name != "jawOpen" and name != "eyeBlinkLeft":
			expected[name] = name
	var bound = {}
	for binding in player._bindings:
		bound[binding[1].trim_prefix("blend_shapes/")] = player._names[binding[0]]
	_check(bound.size() == expected.size(), "%d shapes driven, expected %d: %s" % [bound.size(), expected.size(), str(bound)])
	var worst = 0.0
	var moved = 0
	for t_us in [250000, 500000, 1000000, 1500000]:
		player.show_at(t_us)
		for shape in expected:
			var want = player.weight_at(names.find(expected[shape]), t_us)
			_check(bound.get(shape, "") == expected[shape], "blend shape %s is driven by %s, expected %s" % [shape, bound.get(shape, "nothing"), expected[shape]])
			worst = max(worst, abs(face.get("blend_shapes/" + shape) - want))
			if want > 0.05:
				moved += 1
		_check(face.get("blend_shapes/jawOpen") == 0.5, "the shape jawOpen, which the mapping sends elsewhere, is not driven")
		_check(face.get("blend_shapes/eyeBlinkLeft") == 0.5, "eyeBlinkLeft, mapped to null, is not driven")
	_check(worst <= TOLERANCE, "every driven shape shows its ARKit weight (largest difference %s)" % worst)
	_check(moved >= 8, "the track moved the shapes: %d nonzero weights checked" % moved)
	print("ok: a partial mapping drives %d shapes: its own for jawOpen, mouthSmileLeft (two shapes) and eyeBlinkLeft (none), the ARKit-named shapes for the other %d names" % [bound.size(), expected.size() - 3])

	# Without a mapping, shapes named but for case (as Live Link Face spells them) are driven too.
	var cased = Fixture.make_face(["JawOpen", "MOUTHCLOSE", "mouthFunnel"], "Cased")
	get_root().add_child(cased)
	var on_cased = _new_player(cased, "")
	_check(on_cased.load_track(good) == OK, "a mesh with case-changed ARKit names loads")
	on_cased.show_at(500000)
	for pair in [["JawOpen", "jawOpen"], ["MOUTHCLOSE", "mouthClose"], ["mouthFunnel", "mouthFunnel"]]:
		_check(abs(cased.get("blend_shapes/" + pair[0]) - on_cased.weight_at(names.find(pair[1]), 500000)) <= TOLERANCE, "%s follows %s" % pair)
	print("ok: shapes named but for case follow their ARKit names")


# Whether `value` lies between two readings `a` and `b` of a clock, in either order, within 1 ms.
func _between(value, a, b):
	return value >= min(a, b) - 1000 and value <= max(a, b) + 1000


# Godot's audio-sync recipe, written out here apart from the add-on's: playback position plus the
# time since the last mix, minus the output latency, while the stream plays; a read during which the
# mixer ran (the position moved) is read again.
func _recipe_us(audio):
	var seconds = audio.get_playback_position()
	if audio.playing and not audio.stream_paused:
		var position = -1.0
		while position != audio.get_playback_position():
			position = audio.get_playback_position()
			seconds = position + AudioServer.get_time_since_last_mix() - AudioServer.get_output_latency()
	return int(round(seconds * 1000000.0))
