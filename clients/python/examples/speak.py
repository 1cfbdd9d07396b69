#!/usr/bin/python3
"""Speak text to lipsyncd: timed phonemes from flite or Festival, streamed with Animate.

Usage:
    speak.py [--server HOST:PORT] [--frontend auto|flite|festival] [--voice NAME]
             [--fps N] [--lookahead N] [--model NAME] [--session NAME]
             [--chunk-size N] [--arkit NAME,NAME,...] [--json FILE] [--timeout S] TEXT...

Examples:
    # a table of frames: time (µs), kind, jaw_rotation and a few ARKit weights
    /usr/bin/python3 clients/python/examples/speak.py --server 127.0.0.1:50051 \\
        "Peter picked a peck of pickled peppers."
    # the whole track as JSON (header, frames with all channels and ARKit weights, summary)
    /usr/bin/python3 clients/python/examples/speak.py --json track.json "Hello there."

The phonemes are in Festival's "radio" phone set (flite uses it too) and are sent
in chunks of --chunk-size phonemes, as a streaming TTS front-end would send them.
PYTHONPATH must hold the generated stubs and clients/python (docs/python-client.md).

Exit status: 0 on success, 1 when the server answers with an error (printed as
"speak.py: CODE: details"), 2 for bad arguments, 3 when no TTS front-end works.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))

from lipsync_client import tts  # noqa: E402  (after the path set-up above)

DEFAULT_ARKIT = "jawOpen,mouthClose,mouthFunnel,mouthPucker,mouthPressLeft"


def parse_arguments(argv=None):
    parser = argparse.ArgumentParser(
        prog="speak.py",
        description="Get timed phonemes for TEXT from flite or Festival, stream them to "
        "lipsyncd with Animate (phone set \"radio\") and print the frames or write JSON.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: speak.py --server 127.0.0.1:50051 \"Peter picked a peck of pickled peppers.\"",
    )
    parser.add_argument("text", nargs="+", help="the text to speak (words are joined with spaces)")
    parser.add_argument("--server", default="127.0.0.1:50051", help="lipsyncd address (default %(default)s)")
    parser.add_argument("--frontend", choices=("auto", "flite", "festival"), default="auto",
                        help="TTS front-end for the phoneme timings (default: flite if installed, else Festival)")
    parser.add_argument("--voice", help="front-end voice (flite: slt; Festival: kal_diphone)")
    parser.add_argument("--fps", type=int, default=0, help="frame rate, 1..240 (default: the server's, 30)")
    parser.add_argument("--lookahead", type=int, help="lookahead in segments, 0..7 (default 7: exact)")
    parser.add_argument("--model", default="", help="model name (default: the server's default model)")
    parser.add_argument("--session", default="", help="publish the frames under this session name")
    parser.add_argument("--chunk-size", type=int, default=4, help="phonemes per streamed chunk (default %(default)s)")
    parser.add_argument("--arkit", default=DEFAULT_ARKIT,
                        help="ARKit weights to print in the table, comma-separated (default %(default)s)")
    parser.add_argument("--json", metavar="FILE", help="write the track as JSON to FILE ('-' = stdout) instead of the table")
    parser.add_argument("--timeout", type=float, default=60.0, help="deadline of the call in seconds (default %(default)s)")
    arguments = parser.parse_args(argv)
    if arguments.chunk_size < 1:
        parser.error("--chunk-size must be at least 1")
    return arguments


def frame_record(frame):
    return {
        "index": frame.index,
        "t_us": frame.t_us,
        "kind": frame.kind,
        "channels": frame.channels,
        "arkit": frame.arkit,
    }


def main(argv=None) -> int:
    arguments = parse_arguments(argv)
    text = " ".join(arguments.text)
    try:
        phonemes = tts.timed_phonemes(text, arguments.frontend, arguments.voice)
    except tts.TTSError as error:
        print(f"speak.py: {error}", file=sys.stderr)
        return 3

    import grpc  # imported here so that --help works without grpc installed

    from lipsync_client import Client

    settings = {"phone_set": "radio", "fps": arguments.fps, "model": arguments.model,
                "session": arguments.session}
    if arguments.lookahead is not None:
        settings["lookahead"] = arguments.lookahead
    arkit_names = [name for name in arguments.arkit.split(",") if name]
    table = arguments.json is None
    frames = []
    try:
        with Client(arguments.server, timeout=arguments.timeout) as client:
            stream = client.animate(phonemes, chunk_size=arguments.chunk_size, **settings)
            for frame in stream:
                if table:
                    if frame.index == 0:
                        print(f"# model {stream.header.model}, {stream.header.fps} fps, "
                              f"lookahead {stream.header.lookahead}, {len(phonemes)} phonemes")
                        print("\t".join(["t_us", "kind", "jaw_rotation", *arkit_names]))
                    jaw = frame.channels.get("jaw_rotation")
                    cells = [str(frame.t_us), frame.kind, "-" if jaw is None else f"{jaw:.4f}"]
                    cells += ["-" if frame.arkit.get(name) is None else f"{frame.arkit[name]:.4f}"
                              for name in arkit_names]
                    print("\t".join(cells))
                else:
                    frames.append(frame_record(frame))
    except grpc.RpcError as error:
        print(f"speak.py: {error.code().name}: {error.details()}", file=sys.stderr)
        return 1

    summary = stream.summary
    if table:
        if summary is not None:
            print(f"# {summary.frames} frames, {summary.phonemes} phonemes, {summary.duration_us} µs")
        return 0
    header = stream.header
    document = {
        "text": text,
        "phonemes": [{"label": p.label, "start_us": p.start_us, "end_us": p.end_us} for p in phonemes],
        "header": None if header is None else {
            "model": header.model,
            "fps": header.fps,
            "channels": list(header.channels),
            "arkit_names": list(header.arkit_names),
            "session": header.session,
            "lookahead": header.lookahead,
        },
        "frames": frames,
        "summary": None if summary is None else {
            "frames": summary.frames,
            "phonemes": summary.phonemes,
            "duration_us": summary.duration_us,
        },
    }
    if arguments.json == "-":
        json.dump(document, sys.stdout, indent=1)
        sys.stdout.write("\n")
    else:
        with open(arguments.json, "w", encoding="utf-8") as handle:
            json.dump(document, handle, indent=1)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except BrokenPipeError:  # the reader went away (e.g. piped into head)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(1)
