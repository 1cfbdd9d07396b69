# LipsyncPlayer's live mode with a voice (listen()) inside real Godot (godot3-server), against a
# real lipsyncd started by godot_test.py, one behaviour per LIPSYNC_GODOT_TEST:
#
#   listen     an AudioStreamPlayer plays flite's WAV of real speech (LIPSYNC_WAV) and the player
#              sends its samples to /listen as they play, with the words (LIPSYNC_TEXT), following
#              the session on /ws. Checked: every sample went, never more than listen_ahead_ms
#              ahead of the audio clock; lipsyncd's summary came and the session ended with 1000;
#              the player's clock is the audio clock and the face showed the received frames at it;
#              at the middle of each /p b m/ hold of lipsyncd's offline render of the same WAV
#              (LIPSYNC_OFFLINE; the holds classed by flite's own timings, LIPSYNC_PHONEMES) the live
#              frames are closed, and at its open-vowel peaks open. Prints the weights, the offline
#              ones beside them, and the latency (piece sent to frame received, and frame received
#              against the audio clock).
#   listen_bad_input
#              a player with no AudioStreamPlayer, a stream-less one, an Ogg Vorbis stream (LIPSYNC_OGG), an
#              IMA-ADPCM WAV, an empty sample: refused at once, nothing sent; a voice at 96 kHz:
#              lipsyncd's refusal (INVALID_ARGUMENT, rate) is reported and the follower stops
#              waiting; a viewer address where nothing listens: reported. 8-bit samples convert
#              to 16-bit (s × 256). Then stop() of the real voice (LIPSYNC_WAV) after 0.5 s ends it
#              there: {"end": true} and lipsyncd's summary of what was sent.
#
# Prints "ok: ..." per check passed and "FAIL: ..." per failure; exits 0 only when all passed.
extends "res://checking_tree.gd"

const Fixture = preload("res://face_fixture.gd")
const LipsyncPlayer = preload("res://addons/lipsync/lipsync_player.gd")
const TOLERANCE = 1e-6
const SHOWN = ["jawOpen", "mouthClose", "mouthRollLower", "mouthFunnel"]

var started_ms = 0
var face
var player
var audio
var offline
var samples = []  # [frames the player had, the time it showed, {name: weight shown}, audio clock before, player's clock, audio clock after, unix µs]
var arrivals = []  # [frame time µs, OS.get_ticks_usec() when seen, audio clock then]
var ended = []
var phase = ""


func _init():
	mode = OS.get_environment("LIPSYNC_GODOT_TEST")
	started_ms = OS.get_ticks_msec()
	offline = Fixture.read_json(OS.get_environment("LIPSYNC_OFFLINE"))
	face = Fixture.make_face_for(offline)
	get_root().add_child(face)
	if mode == "listen":
		_start_listening()
	elif mode == "listen_bad_input":
		_refuse_unreadable_players()
	else:
		_check(false, "unknown LIPSYNC_GODOT_TEST '%s'" % mode)
		_finish()


func _new_player(voice):
	var node = LipsyncPlayer.new()
	get_root().add_child(node)
	node.mesh_path = node.get_path_to(face)
	node.model = "default"
	node.live_wait_ms = 3000
	if voice != null:
		node.audio_player_path = node.get_path_to(voice)
	return node


func _new_voice(name, stream):
	var voice = AudioStreamPlayer.new()
	voice.name = name
	voice.stream = stream
	get_root().add_child(voice)
	return voice


# --- listen: flite's speech, live ----------------------------------------------------------------

func _start_listening():
	audio = _new_voice("Voice", Fixture.read_wav(OS.get_environment("LIPSYNC_WAV")))
	if not _check(audio.stream != null, "the WAV reads"):
		_finish()
		return
	player = _new_player(audio)
	player.connect("live_ended", self, "_on_ended")
	if OS.get_environment("LIPSYNC_AHEAD_MS") != "":  # to measure other settings
		player.listen_ahead_ms = int(OS.get_environment("LIPSYNC_AHEAD_MS"))
	var error = player.listen(OS.get_environment("LIPSYNC_WS"), OS.get_environment("LIPSYNC_SESSION"), OS.get_environment("LIPSYNC_TEXT"))
	_check(error == OK, "listen() starts (error %d)" % error)
	phase = "listening"


func _on_ended(code, reason):
	ended = [code, reason]


func _idle(_delta):
	if OS.get_ticks_msec() - started_ms > 30000:
		_check(false, "timed out in phase '%s': %d frames, ended %s, listen_error '%s', live_error '%s'" % [phase, player.frame_times_us.size() if player else 0, str(ended), player.listen_error if player else "", player.live_error if player else ""])
		_finish()
		return false
	if mode == "listen":
		_sample_listening()
	elif mode == "listen_bad_input":
		_step_bad_input()
	return false


func _sample_listening():
	if phase != "listening":
		return
	var shown = {}
	for name in SHOWN:
		shown[name] = face.get("blend_shapes/" + name)
	var had = player.frame_times_us.size()
	var audio_before = LipsyncPlayer.audio_clock_us(audio)
	var clock = player.current_time_us()
	var audio_after = LipsyncPlayer.audio_clock_us(audio)
	if audio.playing:
		samples.append([had, player.last_time_us, shown, audio_before, clock, audio_after, OS.get_system_time_msecs() * 1000])
	var seen = arrivals.size()
	for i in range(seen, had):
		arrivals.append([player.frame_times_us[i], OS.get_ticks_usec(), audio_before])
	if player.listen_error != "" or player.live_error != "":
		_check(false, "listen_error '%s', live_error '%s'" % [player.listen_error, player.live_error])
		_finish()
	elif ended.size() > 0 and player.listen_summary != null and not audio.playing:
		phase = "done"
		_verify_listening()
		_finish()


# [start, end µs, phone] of each closure hold (a closure_start frame followed by a closure_end) of
# the offline render, with the /p b m f v/ of flite's own timings nearest its middle (PocketSphinx's
# alignment of the WAV and flite's timings differ by up to 40 ms).
func _offline_holds():
	var phones = []  # [label, start µs, end µs]
	var start = 0
	var file = File.new()
	file.open(OS.get_environment("LIPSYNC_PHONEMES"), File.READ)
	for item in file.get_as_text().split(" ", false):
		var parts = item.strip_edges().split(":")
		if parts.size() == 2:
			var end = int(round(float(parts[1]) * 1000000.0))
			phones.append([parts[0], start, end])
			start = end
	file.close()
	var holds = []
	var frames = offline["frames"]
	for i in range(frames.size() - 1):
		if frames[i]["kind"] == "closure_start" and frames[i + 1]["kind"] == "closure_end":
			var a = int(frames[i]["t_us"])
			var b = int(frames[i + 1]["t_us"])
			var label = "?"
			var nearest = 1 << 40
			for phone in phones:
				var distance = max(0, max(phone[1] - (a + b) / 2, (a + b) / 2 - phone[2]))
				if ["p", "b", "m", "f", "v"].has(phone[0]) and distance < nearest:
					nearest = distance
					label = phone[0]
			holds.append([a, b, label])
	return holds


# The offline render's jawOpen peaks of 0.25 or more (the open vowels), µs.
func _offline_open_peaks():
	var peaks = []
	var frames = offline["frames"]
	var jaw = offline["arkit_names"].find("jawOpen")
	for i in range(1, frames.size() - 1):
		var w = frames[i]["arkit"][jaw]
		if w >= 0.25 and w >= frames[i - 1]["arkit"][jaw] and w >= frames[i + 1]["arkit"][jaw]:
			peaks.append(int(frames[i]["t_us"]))
	return peaks


func _offline_at(name, t_us):
	var index = offline["arkit_names"].find(name)
	var frames = offline["frames"]
	for i in range(1, frames.size()):
		var t1 = int(frames[i]["t_us"])
		if t_us < t1:
			var t0 = int(frames[i - 1]["t_us"])
			var w0 = float(frames[i - 1]["arkit"][index])
			return w0 + (float(frames[i]["arkit"][index]) - w0) * float(t_us - t0) / float(t1 - t0)
	return float(frames[frames.size() - 1]["arkit"][index])


func _live_at(name, t_us):
	return player.weight_at(player._names.find(name), t_us)


func _verify_listening():
	var stream = audio.stream
	var summary = player.listen_summary
	print("ok: lipsyncd's summary: %s" % JSON.print(summary))
	_check(ended[0] == 1000, "the session ended with 1000 on /ws: %s" % str(ended))
	_check(int(summary.get("frames", -1)) == player.frame_times_us.size(), "the summary counts %s frames, the follower received %d" % [str(summary.get("frames")), player.frame_times_us.size()])
	_check(player.listen_sent_bytes == stream.data.size(), "every sample was sent: %d of %d bytes" % [player.listen_sent_bytes, stream.data.size()])
	# Ahead of the audio clock as the player read it when it sent; a read can be a mix buffer off
	# (Godot 3.2 moves the position and the time since the last mix at two moments; test_player.gd),
	# and the Dummy driver's mixing thread can be a moment late on a busy machine (one pre-check:
	# 312761 us, 1.2 ms past one buffer), so two buffers are allowed.
	var buffer_us = int(1000000.0 * 512 / AudioServer.get_mix_rate())
	_check(player.listen_max_ahead_us <= player.listen_ahead_ms * 1000 + 2 * buffer_us, "the samples ran at most listen_ahead_ms (+ two mix buffers) ahead of the audio clock: %d us" % player.listen_max_ahead_us)
	print("ok: %d bytes sent in %d pieces, at most %d us ahead of the audio clock; the session followed after %d tries" % [player.listen_sent_bytes, player.listen_pieces.size(), player.listen_max_ahead_us, player.live_retries + 1])

	# The player's clock is the audio clock; the face showed the frames it had at its time.
	var clock_error = 0
	var weight_error = 0.0
	var shown_count = 0
	var before_arrival = 0
	for i in range(1, samples.size()):
		var sample = samples[i]
		clock_error = max(clock_error, max(min(sample[3], sample[5]) - 1000 - sample[4], sample[4] - (max(sample[3], sample[5]) + 1000)))
		var had = samples[i - 1][0]
		var t = sample[1]
		if had == 0 or t < 0:
			continue
		if t > player.frame_times_us[had - 1]:
			before_arrival += 1  # its frame had not come: the face held the newest it had
			continue
		shown_count += 1
		for name in sample[2]:
			weight_error = max(weight_error, abs(sample[2][name] - _live_at(name, t)))
	_check(clock_error <= 0, "the player's clock is the audio clock: %d us outside the two readings around it" % clock_error)
	# The anchor lipsyncd was given is when the audio clock was 0: the unix clock less the anchor is
	# the audio clock, give or take a mix buffer and the ms of Godot's unix clock; the Dummy driver
	# then plays at its own pace (slower than the wall clock under load), so only the first 300 ms
	# are held to it and the last is reported.
	var zero = int(player._live_header["utterance_zero_us"])
	var anchor_first = null
	var anchor_last = 0
	for sample in samples:
		if sample[3] > 0:
			var gap = (sample[6] - zero) - sample[3]
			if anchor_first == null and sample[3] <= 300000:
				anchor_first = gap
			anchor_last = gap
	if _check(anchor_first != null, "the audio clock was sampled in its first 300 ms"):
		_check(abs(anchor_first) <= 25000, "the anchor is when the first sample was heard: unix − utterance_zero_us − audio clock = %d us early on" % anchor_first)
		print("ok: the session's anchor: unix clock − utterance_zero_us − audio clock = %d us early on, %d us at the end (the Dummy driver's pace)" % [anchor_first, anchor_last])
	_check(weight_error <= TOLERANCE, "the face showed the received frames at its time (largest difference %s)" % weight_error)
	_check(shown_count >= 20, "frames shown with their frame received: %d" % shown_count)
	print("ok: %d frames drawn on the audio clock with their frames received (weights exact to %s); %d drawn before their frame came (held the newest)" % [shown_count, weight_error, before_arrival])

	# Closed at the /p b m/ middles, open at the open vowels, as offline.
	var closed = 0
	for hold in _offline_holds():
		var t = (hold[0] + hold[1]) / 2
		var jaw = _live_at("jawOpen", t)
		var close = _live_at("mouthClose", t)
		var line = "%s hold %d..%d us, middle %d: live jawOpen %.3f mouthClose %.3f mouthRollLower %.3f; offline jawOpen %.3f mouthClose %.3f" % [hold[2], hold[0], hold[1], t, jaw, close, _live_at("mouthRollLower", t), _offline_at("jawOpen", t), _offline_at("mouthClose", t)]
		if hold[2] == "f" or hold[2] == "v":
			print("ok: (not checked: a tuck) " + line)
			continue  # /f v/: the lower lip tucked, not sealed
		closed += 1
		if _check(close >= jaw - 0.02 and jaw <= 0.2, "closed at the /p b m/ middle: " + line):
			print("ok: closed: " + line)
	var opened = 0
	for t in _offline_open_peaks():
		var line = "open vowel at %d us: live jawOpen %.3f, offline %.3f" % [t, _live_at("jawOpen", t), _offline_at("jawOpen", t)]
		opened += 1
		if _check(_live_at("jawOpen", t) >= 0.25 and _live_at("mouthClose", t) < 0.1, "open at the open vowel: " + line):
			print("ok: open: " + line)
	_check(closed >= 6 and opened >= 4, "checked %d /p b m/ middles and %d open vowels" % [closed, opened])
	print("ok: %d /p b m/ middles closed and %d open vowels open, as in the offline render" % [closed, opened])

	# Latency: from the sending of the piece holding a frame's time to the frame's arrival; and the
	# frame's arrival against the audio clock (negative: before it is heard).
	var latencies = []
	var lateness = []
	var late = []  # frames that came more than a frame (33 ms) after the audio clock passed them
	for arrival in arrivals:
		for piece in player.listen_pieces:
			if piece[0] >= arrival[0]:
				latencies.append((arrival[1] - piece[1]) / 1000)
				break
		lateness.append((arrival[2] - arrival[0]) / 1000)
		if arrival[2] - arrival[0] > 33000:
			late.append("%d us: %d ms" % [arrival[0], (arrival[2] - arrival[0]) / 1000])
	latencies.sort()
	lateness.sort()
	if _check(latencies.size() > 0, "latencies measured"):
		print("ok: latency (piece sent -> frame received), ms: median %d, p95 %d, max %d over %d frames; frame received minus audio clock, ms: median %d, p95 %d, max %d (budget %d ms, sent %d ms ahead)" % [latencies[latencies.size() / 2], latencies[int(latencies.size() * 0.95)], latencies.back(), latencies.size(), lateness[lateness.size() / 2], lateness[int(lateness.size() * 0.95)], lateness.back(), player.listen_latency_ms, player.listen_ahead_ms])
		print("ok: frames that came more than 33 ms after their time: %s" % str(late))


# --- listen_bad_input ----------------------------------------------------------------------------

func _refuse_unreadable_players():
	face.set("blend_shapes/jawOpen", 0.5)
	var url = OS.get_environment("LIPSYNC_WS")
	var nowhere = _new_player(null)
	_check(nowhere.listen(url, "bad") == ERR_UNCONFIGURED, "listen() without an AudioStreamPlayer is refused")
	var silent = _new_player(_new_voice("Silent", null))
	_check(silent.listen(url, "bad") == ERR_UNCONFIGURED, "listen() of a player with no stream is refused")
	var ogg_stream = AudioStreamOGGVorbis.new()  # the same speech, which ffmpeg encoded
	var file = File.new()
	if file.open(OS.get_environment("LIPSYNC_OGG"), File.READ) == OK:
		ogg_stream.data = file.get_buffer(file.get_len())
		file.close()
	var ogg = _new_player(_new_voice("Music", ogg_stream))
	_check(ogg.listen(url, "bad") == ERR_UNAVAILABLE, "listen() of an Ogg Vorbis stream is refused")
	var adpcm_stream = Fixture.make_silence(0.5)
	adpcm_stream.format = AudioStreamSample.FORMAT_IMA_ADPCM
	var adpcm = _new_player(_new_voice("Compressed", adpcm_stream))
	_check(adpcm.listen(url, "bad") == ERR_UNAVAILABLE, "listen() of an IMA-ADPCM WAV is refused")
	var empty = _new_player(_new_voice("Empty", AudioStreamSample.new()))
	_check(empty.listen(url, "bad") == ERR_INVALID_DATA, "listen() of a sample without data is refused")
	for node in [nowhere, silent, ogg, adpcm, empty]:
		_check(node._voice_socket == null and node._socket == null and not node.listening, "nothing was sent")
	var stream_played = false
	for voice in ["Silent", "Music", "Compressed", "Empty"]:
		stream_played = stream_played or get_root().get_node(voice).playing
	_check(not stream_played, "no refused stream was started")
	_check(face.get("blend_shapes/jawOpen") == 0.5, "the face is untouched")

	# 8-bit samples (Godot keeps them signed) become 16-bit little-endian: s × 256.
	var eight = AudioStreamSample.new()
	eight.format = AudioStreamSample.FORMAT_8_BITS
	eight.data = PoolByteArray([0, 1, 127, 128, 255])  # 0, 1, 127, -128, -1
	var converted = LipsyncPlayer.pcm16_of(eight.data, eight.format, 1, 1, 4)
	_check(converted == PoolByteArray([0, 1, 0, 127, 0, 128, 0, 255]), "8-bit samples 1, 127, -128, -1 become 256, 32512, -32768, -256: %s" % str(converted))
	var sixteen = Fixture.make_silence(0.01)
	sixteen.data = PoolByteArray([1, 2, 3, 4, 5, 6, 7, 8])
	_check(LipsyncPlayer.pcm16_of(sixteen.data, sixteen.format, 2, 1, 1) == PoolByteArray([5, 6, 7, 8]), "16-bit stereo frames are sent as they are stored")
	print("ok: players lipsyncd cannot hear are refused at once, nothing sent, the face untouched; 8-bit samples convert")

	# A rate lipsyncd does not take: its refusal is reported, and the follower does not wait on.
	var fast = Fixture.make_silence(1.0, 96000)
	player = _new_player(_new_voice("TooFast", fast))
	_check(player.listen(url, OS.get_environment("LIPSYNC_SESSION")) == OK, "a 96 kHz voice is offered to lipsyncd")
	phase = "refused rate"


func _step_bad_input():
	if phase == "refused rate":
		if player.listen_error != "":
			_check(player.listen_error.find("INVALID_ARGUMENT") >= 0 and player.listen_error.find("rate") >= 0, "lipsyncd's refusal is reported: " + player.listen_error)
			_check(player._socket == null and player._live_retry_at_ms < 0, "the follower stopped waiting for the session")
			print("ok: lipsyncd refused the 96 kHz voice: " + player.listen_error)
			player = _new_player(_new_voice("NoServer", Fixture.make_silence(0.5)))
			_check(player.listen(OS.get_environment("LIPSYNC_NO_SERVER"), "nobody") == OK, "listen() to an address where nothing listens starts")
			phase = "no server"
	elif phase == "no server":
		if player.listen_error != "":
			_check(player.listen_error.find("--http-listen") >= 0, "the error says to start lipsyncd with --http-listen: " + player.listen_error)
			print("ok: no lipsyncd: " + player.listen_error)
			_check(face.get("blend_shapes/jawOpen") == 0.5, "the face is untouched")
			# The real voice, stopped after 0.5 s: the voice ends there, with lipsyncd's summary.
			player = _new_player(_new_voice("Stopped", Fixture.read_wav(OS.get_environment("LIPSYNC_WAV"))))
			_check(player.listen(OS.get_environment("LIPSYNC_WS"), "godot-stopped") == OK, "listen() of the voice to stop starts")
			phase = "to stop"
	elif phase == "to stop":
		if LipsyncPlayer.audio_clock_us(player._audio) >= 500000:
			player.stop()
			phase = "stopped"
	elif phase == "stopped":
		if player.listen_summary != null or player.listen_error != "":
			var sent_us = player.listen_sent_bytes * 1000000 / (2 * player._voice_rate)
			var summary = player.listen_summary if player.listen_summary != null else {}
			_check(player.listen_error == "", "no error: " + player.listen_error)
			_check(sent_us >= 500000 and sent_us <= 500000 + player.listen_ahead_ms * 1000 + 50000, "stopped at 0.5 s: %d us of the voice sent" % sent_us)
			_check(int(summary.get("duration_us", 0)) <= sent_us + 50000 and int(summary.get("frames", 0)) > 0, "lipsyncd's summary covers what was sent: %s" % JSON.print(summary))
			print("ok: stop() at 0.5 s ended the voice: %d us sent, lipsyncd's summary %s" % [sent_us, JSON.print(summary)])
			_finish()
