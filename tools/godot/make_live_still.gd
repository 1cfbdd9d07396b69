# A still of the Godot add-on's live mode with a voice, for docs/integrations.md: lipsyncd's viewer
# face (viewer_face_scene.gd), an AudioStreamPlayer playing a WAV and a LipsyncPlayer that listen()s
# to it: the samples go to a real lipsyncd as they play and the face shows the frames that come
# back, on the audio clock. The picture is the first frame drawn at or after T_US of the voice,
# captioned; the voice then plays to its end, so that lipsyncd's summary closes the session.
# Rendered by Godot 3 under Xvfb (the headless runtime draws nothing); run by make_live_still.sh.
#   godot3 --path PROJECT --resolution 480x360 -s res://make_live_still.gd --
#          FACE WAV VIEWER_URL SESSION TRANSCRIPT T_US OUT.png
extends SceneTree

const Fixture = preload("res://face_fixture.gd")
const LipsyncPlayer = preload("res://addons/lipsync/lipsync_player.gd")
const Scene = preload("res://viewer_face_scene.gd")
const kTimeoutMs = 20000

var _player
var _audio
var _at_us = 0
var _out = ""
var _saved = false
var _started_ms = 0


# The session and the time the face shows, under it.
class Caption extends Label:
	var _player
	var _session

	func _init(player, session):
		_player = player
		_session = session
		rect_position = Vector2(10, 338)

	func _process(_delta):
		text = "LipsyncPlayer.listen(): session '%s', live; %.2f s into the voice" % [_session,
				_player.last_time_us / 1e6]


func _init():
	var args = Scene.script_args(7, "-s res://make_live_still.gd -- FACE WAV VIEWER_URL SESSION TRANSCRIPT T_US OUT.png")
	if args == null:
		quit(2)
		return
	var face = Scene.stage(root, args[0])
	_audio = AudioStreamPlayer.new()
	_audio.name = "Voice"
	_audio.stream = Fixture.read_wav(args[1])
	if face == null or _audio.stream == null:
		push_error("cannot read the face or the WAV " + args[1])
		quit(1)
		return
	root.add_child(_audio)
	_at_us = int(args[5])
	_out = args[6]
	_player = LipsyncPlayer.new()
	root.add_child(_player)
	_player.mesh_path = _player.get_path_to(face)
	_player.audio_player_path = _player.get_path_to(_audio)
	root.add_child(Caption.new(_player, args[3]))  # after the player: it reads the time just shown
	_started_ms = OS.get_ticks_msec()
	if _player.listen(args[2], args[3], args[4]) != OK:
		quit(1)
		return


func _idle(_delta):
	if _player.listen_error != "" or _player.live_error != "":
		push_error("listen_error '%s', live_error '%s'" % [_player.listen_error, _player.live_error])
		quit(1)
		return true
	if OS.get_ticks_msec() - _started_ms > kTimeoutMs:
		push_error("timed out: %d frames, %s" % [_player.frame_times_us.size(), str(_player.listen_summary)])
		quit(1)
		return true
	# The viewport holds what was drawn after the last idle step: the face (and the caption) at the
	# time last shown then (the nodes process after this script's _idle).
	if not _saved and _player.last_time_us >= _at_us:
		_saved = true
		var frames = _player.frame_times_us
		print("%s: the face at %d us of the voice (%d frames received, the newest for %d us)" % [_out,
				_player.last_time_us, frames.size(), frames.back() if frames.size() > 0 else -1])
		if Scene.save_view(root, _out) != OK:
			quit(1)
			return true
	if _saved and _player.listen_summary != null and _player.live_done:
		print("lipsyncd's summary: %s" % str(_player.listen_summary))
		quit(0)
		return true
	return false
