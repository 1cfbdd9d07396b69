"""Tracks from a running lipsyncd, over gRPC, for the Blender operators.

The add-on's zip carries the project's Python client (lipsync_client) and its generated
stubs (package lipsync.v1) under ``_vendor``; gRPC itself (grpcio, protobuf) must be
importable in Blender's Python (Debian's Blender runs on the system Python, where
python3-grpcio provides it). Nothing here imports grpc until a call is made, so importing a
track file works without it.

* render_phonemes(): the phonemes of a file (``flite -psdur`` output, or lipsync utterance
  JSON) go to Animate, which renders the frames Render would (lookahead 7) and sends them back
  as they are made, so the progress bar follows the utterance;
* speak(): the server speaks a text with espeak-ng (Speak) and returns the audio and the
  frames on one clock.

Both return a track.Track (the same curves a track file gives), and failures become LiveError
with a message that says what to do (no server, no grpc, a refused phoneme).
"""

from __future__ import annotations

import json
import os
import sys
from typing import Callable, List, Optional, Tuple

from .track import Track

_VENDOR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "_vendor")

Progress = Callable[[float], None]  # fraction done, 0..1


class LiveError(RuntimeError):
    """A live render that could not be done; the message says what to do."""


def _client_module():
    """lipsync_client.client (with grpc), from the zip's _vendor or an installed copy."""
    if os.path.isdir(_VENDOR) and _VENDOR not in sys.path:
        sys.path.insert(0, _VENDOR)
    try:
        import grpc  # noqa: F401
    except ImportError:
        raise LiveError(
            "The Python module grpc is not available in Blender's Python. On Debian: "
            "apt-get install python3-grpcio python3-protobuf (Debian's Blender runs on the system "
            "Python); with a blender.org build: <blender>/<version>/python/bin/python3.* -m pip "
            "install grpcio protobuf") from None
    try:
        from lipsync_client import client
    except Exception as error:  # ImportError, or protobuf's TypeError for a runtime too old for the stubs
        raise LiveError(f"The lipsyncd Python client could not be loaded ({type(error).__name__}: {error}): "
                        "reinstall the add-on from the zip the build makes (build/lipsync_blender.zip); "
                        "the stubs need protobuf 3.20 or newer") from None
    return client


def read_phonemes(path: str) -> Tuple[List[Tuple[str, int, int]], str]:
    """(label, start_us, end_us) phonemes and their phone set, from ``flite -psdur`` output or
    lipsync utterance JSON (docs/input-formats.md). Other formats: `lipsync render` them."""
    if _VENDOR not in sys.path and os.path.isdir(_VENDOR):
        sys.path.insert(0, _VENDOR)
    from lipsync_client import tts  # pure Python, no grpc

    try:
        with open(path, encoding="utf-8-sig") as stream:
            text = stream.read()
    except (OSError, UnicodeDecodeError) as error:
        raise LiveError(f"{path}: cannot read the phoneme file: {error}") from None
    if not text.lstrip().startswith("{"):
        try:
            phonemes = tts.parse_flite_psdur(text)
        except tts.TTSError as error:
            raise LiveError(f"{path}: not `flite -psdur` output nor lipsync JSON ({error}); for "
                            "TextGrid, .lab, .PHN or .pho files run `lipsync render FILE --format "
                            "json` and import the track") from None
        if not phonemes:
            raise LiveError(f"{path}: no phonemes")
        return [tuple(p) for p in phonemes], "radio"
    try:
        document = json.loads(text, parse_float=str, parse_int=str)
    except json.JSONDecodeError as error:
        raise LiveError(f"{path}:{error.lineno}: not valid JSON ({error.msg})") from None
    if not isinstance(document, dict) or not isinstance(document.get("phonemes"), list):
        raise LiveError(f"{path}: lipsync utterance JSON needs a \"phonemes\" list (a track file? "
                        "use Import Track instead)")
    phonemes = []
    for i, item in enumerate(document["phonemes"], 1):
        if not isinstance(item, dict) or not isinstance(item.get("label"), str):
            raise LiveError(f"{path}: phoneme {i}: needs a \"label\" string")
        times = []
        for name in ("start", "end"):
            seconds, micros = item.get(name), item.get(name + "_us")
            try:
                if micros is not None and seconds is None and str(micros).isdigit():
                    times.append(int(micros))
                elif seconds is not None and micros is None:
                    times.append(tts.seconds_to_us(str(seconds)))
                else:
                    raise ValueError(f"give \"{name}\" (s) or \"{name}_us\" (integer µs), once")
            except ValueError as error:
                raise LiveError(f"{path}: phoneme {i} ({item['label']!r}): {error}") from None
        phonemes.append((item["label"].strip(), times[0], times[1]))
    if not phonemes:
        raise LiveError(f"{path}: no phonemes")
    phone_set = document.get("phone_set") if isinstance(document.get("phone_set"), str) else ""
    return phonemes, phone_set or "arpabet"


def _connect(client_module, address: str, timeout_s: float):
    import grpc

    client = client_module.Client(address, timeout=timeout_s)
    try:
        client.wait_ready(timeout=min(timeout_s, 5.0))
    except grpc.FutureTimeoutError:
        client.close()
        raise LiveError(f"No lipsyncd answers at {address}: start it (lipsyncd --listen {address}) "
                        "or set the server address in the add-on's preferences") from None
    return client


def _rpc_error(error, address: str, what: str) -> LiveError:
    return LiveError(f"lipsyncd at {address} refused the {what}: {error.code().name}: {error.details()}")


def _to_track(header, frames, source: str) -> Track:
    arkit = {name: [f.arkit[name] for f in frames] for name in header.arkit_names}
    channels = {name: [f.channels[name] for f in frames] for name in header.channels}
    return Track(source, "lipsyncd", [f.t_us for f in frames], [f.kind for f in frames], arkit,
                 channels, header.model or None, header.fps or None)


def _settings(model: str, fps: int) -> dict:
    settings = {}
    if model:
        settings["model"] = model
    if fps:
        settings["fps"] = fps
    return settings


def render_phonemes(address: str, phonemes, phone_set: str, *, model: str = "", fps: int = 0,
                    timeout_s: float = 60.0, progress: Optional[Progress] = None) -> Track:
    client_module = _client_module()
    import grpc

    end_us = max(p[2] for p in phonemes) or 1
    client = _connect(client_module, address, timeout_s)
    try:
        stream = client.animate(phonemes, phone_set=phone_set, **_settings(model, fps))
        frames = []
        for frame in stream:
            frames.append(frame)
            if progress:
                progress(min(frame.t_us / end_us, 1.0))
    except grpc.RpcError as error:
        raise _rpc_error(error, address, "phonemes") from None
    except ValueError as error:  # a malformed message (lipsync_client's checks)
        raise LiveError(f"lipsyncd at {address} sent a malformed track: {error}") from None
    finally:
        client.close()
    if not frames or stream.header is None:
        raise LiveError(f"lipsyncd at {address} sent no frames")
    return _to_track(stream.header, frames, f"lipsyncd {address}")


def speak(address: str, text: str, wav_path: str, *, voice: str = "", model: str = "",
          fps: int = 0, timeout_s: float = 60.0, progress: Optional[Progress] = None) -> Track:
    """Has lipsyncd speak `text`; writes the audio to `wav_path` and returns the track."""
    client_module = _client_module()
    import grpc

    client = _connect(client_module, address, timeout_s)
    if progress:
        progress(0.1)
    try:
        speech = client.speak(text, voice=voice, **_settings(model, fps))
    except grpc.RpcError as error:
        raise _rpc_error(error, address, "text") from None
    except ValueError as error:  # a malformed or cut-short stream (lipsync_client's checks)
        raise LiveError(f"lipsyncd at {address} sent a malformed answer: {error}") from None
    finally:
        client.close()
    if progress:
        progress(0.8)
    if not speech.track.frames:
        raise LiveError(f"lipsyncd at {address} spoke no frames for {text!r}")
    try:
        speech.write_wav(wav_path)
    except OSError as error:
        raise LiveError(f"Cannot write the speech to {wav_path!r}: {error.strerror}") from None
    return _to_track(speech.track.header, speech.track.frames, f"lipsyncd {address}")
