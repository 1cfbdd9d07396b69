# LipsyncPlayer's live mode inside real Godot (godot3-server), against a real lipsyncd started by
# godot_test.py: follow() the session LIPSYNC_SESSION on the viewer's WebSocket LIPSYNC_WS while a
# producer streams real speech into it in real time with a "unix" media-clock anchor, and check:
#   - the frames received equal the same phonemes rendered offline (LIPSYNC_EXPECTED: lipsync render);
#   - every frame the face showed was the anchor's utterance time (unix now − utterance_zero_us)
#     and the track's weights at that time (linear between frames), closures sealed on the mesh;
#   - the session's end arrives (live_ended, code 1000).
# With LIPSYNC_GODOT_TEST=no_server, follow() of an address where nothing listens reports an error
# and leaves the face untouched; with no_session, a session that never starts is reported after
# live_wait_ms (lipsyncd's NOT_FOUND, asked again every 250 ms until then); with bad_address,
# follow() of something that is not a viewer address is refused at once.
extends "res://checking_tree.gd"

const Fixture = preload("res://face_fixture.gd")
const LipsyncPlayer = preload("res://addons/lipsync/lipsync_player.gd")
const TOLERANCE = 1e-6

var started_ms = 0
var face
var player
var expected
var samples = []  # [unix µs now, player's time, frames received, {name: weight shown}]
var ended = []
var header = null
var after_end_steps = 0
var audio = null
var audio_start = null  # [anchor's utterance time, audio clock] when the audio was first seen playing


func _init():
	mode = OS.get_environment("LIPSYNC_GODOT_TEST")
	started_ms = OS.get_ticks_msec()
	expected = Fixture.read_json(OS.get_environment("LIPSYNC_EXPECTED"))
	face = Fixture.make_face_for(expected)
	get_root().add_child(face)
	player = LipsyncPlayer.new()
	get_root().add_child(player)
	player.mesh_path = player.get_path_to(face)
	player.model = "default"
	player.connect("live_header", self, "_on_header")
	player.connect("live_ended", self, "_on_ended")
	if mode == "live":
		# The session's audio (silence of its length here) starts when utterance time 0 comes.
		var end_us = int(expected["frames"][expected["frames"].size() - 1]["t_us"])
		audio = AudioStreamPlayer.new()
		audio.stream = Fixture.make_silence(end_us / 1000000.0 + 0.5)
		get_root().add_child(audio)
		player.audio_player_path = player.get_path_to(audio)
	if mode == "no_server" or mode == "no_session" or mode == "bad_address":
		face.set("blend_shapes/jawOpen", 0.5)
		player.live_wait_ms = 1000
	var error = player.follow(OS.get_environment("LIPSYNC_WS"), OS.get_environment("LIPSYNC_SESSION"))
	if mode == "bad_address":
		_check(error == ERR_INVALID_PARAMETER, "follow() of '%s' is refused at once (error %d)" % [OS.get_environment("LIPSYNC_WS"), error])
		_check(face.get("blend_shapes/jawOpen") == 0.5 and player.frame_times_us.empty(), "the face is untouched")
		print("ok: a bad viewer address is refused")
		_finish()
		return
	_check(error == OK, "follow() starts (error %d)" % error)


func _on_header(h):
	header = h


func _on_ended(code, reason):
	ended = [code, reason]


func _unix_now_us():
	return OS.get_system_time_msecs() * 1000


func _idle(_delta):
	if OS.get_ticks_msec() - started_ms > 30000:
		_check(false, "timed out: header %s, %d frames, ended %s, error '%s'" % [str(header != null), player.frame_times_us.size(), str(ended), player.live_error])
		_finish()
		return false
	if mode == "no_session":
		if player.live_error != "":
			_check(player.live_error.find("NOT_FOUND") < 0 and player.live_error.find("lipsync stream INPUT --session nobody") >= 0, "the error says to start the producer: " + player.live_error)
			_check(player.live_retries >= 2, "asked again while waiting: %d times" % player.live_retries)
			_check(face.get("blend_shapes/jawOpen") == 0.5, "the face is untouched")
			print("ok: no such session, after %d tries in %d ms: %s" % [player.live_retries + 1, OS.get_ticks_msec() - started_ms, player.live_error])
			_finish()
		return false
	if mode == "no_server":
		if player.live_error != "":
			_check(player.live_error.find("--http-listen") >= 0, "the error says to start lipsyncd with --http-listen: " + player.live_error)
			_check(face.get("blend_shapes/jawOpen") == 0.5, "the face is untouched")
			print("ok: no lipsyncd: " + player.live_error)
			_finish()
		return false
	if header == null:
		return false
	# What the player showed last frame, at its time.
	var shown = {}
	for name in ["jawOpen", "mouthClose", "mouthFunnel", "mouthPucker", "mouthRollLower"]:
		shown[name] = face.get("blend_shapes/" + name)
	# The player's clock now, between two readings of the unix clock (a busy machine may pause the
	# script between two calls: CI saw 3.3 ms between the reads when they were taken one after the other).
	var unix_before_us = _unix_now_us()
	var player_now_us = player.current_time_us()
	samples.append([unix_before_us, player.last_time_us, player.frame_times_us.size(), shown, player_now_us, _unix_now_us()])
	if audio_start == null and audio.playing:
		audio_start = [player.current_time_us(), LipsyncPlayer.audio_clock_us(audio)]
	var last_t = int(expected["frames"][expected["frames"].size() - 1]["t_us"])
	if ended.size() > 0 and player.last_time_us > last_t + 100000:
		_verify()
		_finish()
	return false


# The expected track's weight of `name` at `t_us`, written out independently of the add-on.
func _expected_at(name, t_us):
	var index = expected["arkit_names"].find(name)
	var frames = expected["frames"]
	if t_us <= int(frames[0]["t_us"]):
		return float(frames[0]["arkit"][index])
	for i in range(1, frames.size()):
		var t1 = int(frames[i]["t_us"])
		if t_us < t1:
			var t0 = int(frames[i - 1]["t_us"])
			var w0 = float(frames[i - 1]["arkit"][index])
			var w1 = float(frames[i]["arkit"][index])
			return w0 + (w1 - w0) * float(t_us - t0) / float(t1 - t0)
	return float(frames[frames.size() - 1]["arkit"][index])


func _verify():
	_check(header["clock"] == "unix" and header["utterance_zero_us"] > 0, "the header carries a unix anchor: %s %d" % [header["clock"], header["utterance_zero_us"]])
	_check(ended[0] == 1000, "the session ended with 1000: %s" % str(ended))
	# The audio started at utterance time 0, not before: when first seen playing, it was where the
	# anchor was (within a frame of the main loop, and the mix's granularity).
	if _check(audio_start != null, "the audio started"):
		_check(audio_start[0] >= 0 and abs(audio_start[0] - audio_start[1]) <= 100000, "the audio started at the anchor's time: anchor %d us, audio %d us" % audio_start)
		print("ok: the audio started with the anchor at %d us, its clock then %d us" % audio_start)
	var waited = int(OS.get_environment("LIPSYNC_EXPECT_RETRIES"))
	_check(player.live_retries >= waited, "asked again for the session before it started: %d times (expected at least %d)" % [player.live_retries, waited])
	# The frames received are the offline track's.
	var frames = expected["frames"]
	var names = expected["arkit_names"]
	_check(player.frame_times_us.size() == frames.size(), "%d frames received, the offline track has %d" % [player.frame_times_us.size(), frames.size()])
	var worst = 0.0
	for i in range(min(frames.size(), player.frame_times_us.size())):
		if not _check(player.frame_times_us[i] == int(frames[i]["t_us"]), "frame %d at %d us, offline %d" % [i, player.frame_times_us[i], int(frames[i]["t_us"])]):
			break
		for n in range(names.size()):
			worst = max(worst, abs(player.weight_at(n, player.frame_times_us[i]) - float(frames[i]["arkit"][n])))
	_check(worst <= TOLERANCE, "received weights equal the offline track's (largest difference %s)" % worst)
	# Every frame shown: the anchor's time, the track's weights at it.
	var zero = int(header["utterance_zero_us"])
	var inside = 0
	var in_closure = 0
	var open = 0
	var clock_error = 0
	var anchor_error = 0
	var weight_error = 0.0
	var closures = _closure_holds()
	for i in range(1, samples.size()):
		var sample = samples[i]
		var t = sample[1]
		# Frames the player had when it showed this (its _process ran after the previous sample, or
		# in the same frame before this one: at least the previous sample's count).
		var had = samples[i - 1][2]
		if had == 0:
			continue  # nothing shown yet
		# The sample was taken after the frame shown; the anchor's time then was at most one frame later.
		var anchor_t = sample[0] - zero
		clock_error = max(clock_error, abs(anchor_t - t))
		# Outside [before, after] of the two unix readings, each read in whole ms (so up to 1 ms early,
		# like the player's own offset).
		var anchor_after_t = sample[5] - zero
		anchor_error = max(anchor_error, max(anchor_t - 1000 - sample[4], sample[4] - (anchor_after_t + 1000)))
		if t < 0 or t > int(frames[frames.size() - 1]["t_us"]):
			continue
		if had < frames.size() and t > player.frame_times_us[had - 1]:
			continue  # the frame had not arrived (not expected with lipsync stream's playout delay)
		inside += 1
		for name in sample[3]:
			weight_error = max(weight_error, abs(sample[3][name] - _expected_at(name, t)))
		if sample[3]["jawOpen"] >= 0.25:
			open += 1
		for hold in closures:
			if t >= hold[0] and t <= hold[1]:
				in_closure += 1
				_check(sample[3]["mouthClose"] >= sample[3]["jawOpen"] - 0.02, "live at %d us, inside the /p b m/ hold %s: jawOpen %f, mouthClose %f" % [t, str(hold), sample[3]["jawOpen"], sample[3]["mouthClose"]])
	_check(anchor_error <= 1000, "the player's clock is the anchor's utterance time: %d us outside the two unix readings around it (each read in ms)" % anchor_error)
	# A sanity bound only: the gap is one frame of Godot's main loop, which a loaded machine stretches.
	_check(clock_error <= 250000, "the face followed the anchor: largest gap %d us" % clock_error)
	_check(weight_error <= TOLERANCE, "the face showed the track's weights at its time (largest difference %s)" % weight_error)
	_check(inside >= 30, "frames shown during the utterance: %d" % inside)
	_check(open >= 3, "frames with the mouth open: %d" % open)
	_check(in_closure >= 3, "frames inside /p b m/ holds: %d" % in_closure)
	print("ok: live: followed after %d tries; %d frames received = offline; %d frames shown during the utterance (%d open, %d inside /p b m/ holds, all sealed); the player's clock at most %d us outside the two unix readings around it, the face shown at most %d us behind it (one frame); weights exact to %s" % [player.live_retries + 1, player.frame_times_us.size(), inside, open, in_closure, anchor_error, clock_error, weight_error])


# [start µs, end µs] of each /p b m/ hold of the expected track: a closure_start followed by a
# closure_end, both sealed (mouthClose ≥ jawOpen − 0.02; /f v/ holds are not sealed).
func _closure_holds():
	var holds = []
	var frames = expected["frames"]
	var names = expected["arkit_names"]
	var jaw = names.find("jawOpen")
	var close = names.find("mouthClose")
	for i in range(frames.size() - 1):
		if frames[i]["kind"] != "closure_start" or frames[i + 1]["kind"] != "closure_end":
			continue
		var sealed = true
		for f in [frames[i], frames[i + 1]]:
			if f["arkit"][close] < f["arkit"][jaw] - 0.02:
				sealed = false
		if sealed:
			holds.append([int(frames[i]["t_us"]), int(frames[i + 1]["t_us"])])
	return holds
