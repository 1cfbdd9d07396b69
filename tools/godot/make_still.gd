# A still of the Godot add-on at work, for docs/integrations.md: lipsyncd's viewer face
# (viewer_face_scene.gd), a LipsyncPlayer showing a track at one instant, rendered by Godot 3 under
# Xvfb (the headless runtime draws nothing). Run by tools/godot/make_still.sh.
#   godot3 --path PROJECT --resolution 480x360 -s res://make_still.gd -- FACE TRACK T_US OUT.png
extends SceneTree

const LipsyncPlayer = preload("res://addons/lipsync/lipsync_player.gd")
const Scene = preload("res://viewer_face_scene.gd")

var _frames_left = 8
var _out = ""


func _init():
	var args = Scene.script_args(4, "-s res://make_still.gd -- FACE TRACK T_US OUT.png")
	if args == null:
		quit(2)
		return
	var face = Scene.stage(root, args[0])
	if face == null:
		quit(1)
		return
	_out = args[3]
	var player = LipsyncPlayer.new()
	player.mesh_path = face.get_path()
	root.add_child(player)
	if player.load_track(args[1]) != OK:
		quit(1)
		return
	player.show_at(int(args[2]))


func _idle(_delta):
	_frames_left -= 1
	if _frames_left > 0:
		return false
	quit(0 if Scene.save_view(root, _out) == OK else 1)
	return true
