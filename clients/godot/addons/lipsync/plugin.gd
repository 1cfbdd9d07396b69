# Registers the LipsyncPlayer node with the editor (Project Settings > Plugins > lipsync).
tool
extends EditorPlugin


func _enter_tree():
	add_custom_type("LipsyncPlayer", "Node", preload("lipsync_player.gd"), null)


func _exit_tree():
	remove_custom_type("LipsyncPlayer")
