# What the Godot test scripts share: a SceneTree that counts failed checks, prints "FAIL: ..." for
# each, and quits with status 1 if any failed (godot_test.py reads the output and the status).
extends SceneTree

var failures = 0
var mode = ""  # LIPSYNC_GODOT_TEST: the behaviour a script checks


func _check(condition, message):
	if condition:
		return true
	_fail(message)
	return false


func _fail(message):
	failures += 1
	print("FAIL: " + message)


func _finish():
	print("%s: %d failure(s)" % [mode, failures])
	quit(1 if failures > 0 else 0)
