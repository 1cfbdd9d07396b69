"""lipsync_client: a small Python client for lipsyncd (gRPC API lipsync.v1).

    from lipsync_client import Client, timed_phonemes

    phonemes = timed_phonemes("Peter picked a peck of pickled peppers.")  # flite or Festival
    with Client("127.0.0.1:50051") as client:
        for frame in client.animate(phonemes, phone_set="radio"):
            print(frame.t_us, frame.kind, frame.channels.get("jaw_rotation"))

The gRPC stubs (package ``lipsync.v1``: ``lipsync_pb2``, ``lipsync_pb2_grpc``) are
generated at build time (CMake target ``lipsync_python_stubs``) and must be on
``sys.path`` together with this package; see docs/python-client.md.

``lipsync_client.tts`` needs neither grpc nor the stubs; the client classes are
imported on first use.
"""

from .tts import (
    TimedPhoneme,
    TTSError,
    TTSUnavailableError,
    festival_phonemes,
    flite_phonemes,
    parse_flite_psdur,
    seconds_to_us,
    timed_phonemes,
)

_CLIENT_NAMES = (
    "Client", "make_channel", "Frame", "FrameStream", "ListenStream", "BatchArrival", "Speech", "Track", "Words",
    "make_settings", "KIND_NAMES",
)

__all__ = [
    "TimedPhoneme",
    "TTSError",
    "TTSUnavailableError",
    "festival_phonemes",
    "flite_phonemes",
    "parse_flite_psdur",
    "seconds_to_us",
    "timed_phonemes",
    *_CLIENT_NAMES,
]


def __getattr__(name):  # PEP 562: import grpc and the stubs only when the client is used
    if name in _CLIENT_NAMES:
        from . import client

        return getattr(client, name)
    raise AttributeError(f"module 'lipsync_client' has no attribute {name!r}")
