# A protobuf reader for what lipsyncd's viewer WebSocket (/ws?session=NAME) sends: each binary
# message is one serialised lipsync.v1.TrackMessage (proto/lipsync/v1/lipsync.proto), the bytes a
# gRPC Subscribe call receives. Only the fields a player needs are decoded (the header's model,
# fps, ARKit names and media-clock anchor; the batches' times, kinds and ARKit weights; the
# summary); other fields are skipped by wire type, so a newer server's additions do not break it.
# Repeated scalars are read packed or unpacked, as proto3 parsers must. A port of
# server/web/track_decoder.js. GDScript ints are 64-bit, so int64 times are exact.
extends Reference

var _bytes = PoolByteArray()
var _floats = StreamPeerBuffer.new()
var _pos = 0
var _end = 0
var error = ""  # set when the message is malformed


# One TrackMessage: {"header": {...}} or {"frames": {...}} or {"summary": {...}}; {} and `error`
# set when the bytes are not a TrackMessage.
func decode_track_message(bytes):
	_bytes = bytes
	_floats.data_array = bytes
	_pos = 0
	_end = bytes.size()
	error = ""
	var out = {}
	while _pos < _end and error == "":
		var key = _varint()
		var field = key >> 3
		var wire = key & 7
		if wire == 2 and field >= 1 and field <= 3:
			var length = _varint()
			var stop = _pos + length
			if stop > _end:
				error = "truncated field %d" % field
				break
			if field == 1:
				out["header"] = _header(stop)
			elif field == 2:
				out["frames"] = _batch(stop)
			else:
				out["summary"] = _summary(stop)
			_pos = stop
		else:
			_skip(wire)
	if error != "":
		return {}
	return out


func _varint():
	var value = 0
	var shift = 0
	while true:
		if _pos >= _end or shift > 63:
			error = "truncated varint"
			return 0
		var b = _bytes[_pos]
		_pos += 1
		value |= (b & 0x7f) << shift
		shift += 7
		if b < 0x80:
			return value
	return value


func _float():
	if _pos + 4 > _end:
		error = "truncated float"
		return 0.0
	_floats.seek(_pos)
	_pos += 4
	return _floats.get_float()


func _string(stop):
	var length = _varint()
	if _pos + length > stop:
		error = "truncated string"
		return ""
	var text = _bytes.subarray(_pos, _pos + length - 1).get_string_from_utf8() if length > 0 else ""
	_pos += length
	return text


func _skip(wire):
	if wire == 0:
		_varint()
	elif wire == 1:
		_pos += 8
	elif wire == 2:
		_pos += _varint()
	elif wire == 5:
		_pos += 4
	else:
		error = "unsupported wire type %d" % wire
	if _pos > _end:
		error = "truncated field"


# The TrackHeader's fields up to `stop`; unknown ones are skipped.
func _header(stop):
	var header = {"model": "", "fps": 0, "arkit_names": [], "session": "", "clock": "", "utterance_zero_us": 0}
	while _pos < stop and error == "":
		var key = _varint()
		var field = key >> 3
		var wire = key & 7
		if field == 1 and wire == 2:
			header["model"] = _string(stop)
		elif field == 2 and wire == 0:
			header["fps"] = _varint()
		elif field == 4 and wire == 2:
			header["arkit_names"].append(_string(stop))
		elif field == 5 and wire == 2:
			header["session"] = _string(stop)
		elif field == 6 and wire == 2:
			var length = _varint()
			var inner_stop = _pos + length
			while _pos < inner_stop and error == "":
				var inner_key = _varint()
				if inner_key == (1 << 3 | 2):
					header["clock"] = _string(inner_stop)
				elif inner_key == (2 << 3 | 0):
					header["utterance_zero_us"] = _varint()
				else:
					_skip(inner_key & 7)
			_pos = inner_stop
		else:
			_skip(wire)
	return header


func _batch(stop):
	var batch = {"first_frame": 0, "t_us": [], "kinds": [], "arkit": PoolRealArray()}
	while _pos < stop and error == "":
		var key = _varint()
		var field = key >> 3
		var wire = key & 7
		if field == 1 and wire == 0:
			batch["first_frame"] = _varint()
		elif (field == 2 or field == 3) and (wire == 0 or wire == 2):
			var out = batch["t_us"] if field == 2 else batch["kinds"]
			if wire == 0:
				out.append(_varint())
			else:
				var inner_stop = _pos + _varint()
				while _pos < inner_stop and error == "":
					out.append(_varint())
		elif field == 5 and (wire == 5 or wire == 2):
			var arkit = batch["arkit"]
			if wire == 5:
				arkit.append(_float())
			else:
				var inner_stop = _pos + _varint()
				if inner_stop > stop:
					error = "truncated packed floats"
					break
				while _pos < inner_stop:
					arkit.append(_float())
			batch["arkit"] = arkit  # PoolRealArray is a value: store the grown copy
		else:
			_skip(wire)
	return batch


func _summary(stop):
	var summary = {"frames": 0, "phonemes": 0, "duration_us": 0}
	while _pos < stop and error == "":
		var key = _varint()
		var field = key >> 3
		var wire = key & 7
		if wire == 0 and field >= 1 and field <= 3:
			summary[["frames", "phonemes", "duration_us"][field - 1]] = _varint()
		else:
			_skip(wire)
	return summary
