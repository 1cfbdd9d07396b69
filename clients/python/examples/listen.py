#!/usr/bin/python3
"""Pipe a TTS's speech into lipsyncd as it is synthesised (Listen), and measure the latency.

Usage:
    listen.py [--server HOST:PORT] [--session NAME] [--voice NAME] [--speed WPM]
              [--piece-ms MS] [--realtime] [--latency-ms MS] [--no-transcript]
              [--fps N] [--timeout S] TEXT...

Example:
    # watch it in the viewer (docs/viewer.md) under the session "demo"
    /usr/bin/python3 clients/python/examples/listen.py --server 127.0.0.1:50051 \\
        --session demo --realtime "Papa bought five more big maps."

espeak-ng (Debian package espeak-ng) writes a WAV to its standard output as it
synthesises (`espeak-ng --stdout TEXT`). This script reads the WAV's header from the
pipe, then sends the samples as raw 16-bit PCM pieces with client.listen(), each as
soon as the pipe gives it (at most --piece-ms of audio; with --realtime, pieces of
exactly --piece-ms, piece k leaving k x --piece-ms after the first, as a speaker
would say them). The text goes along as the transcript unless --no-transcript.

At the end it prints one line per frame batch received: its frames, their times, and
the latency of its first and last frame (from sending the audio piece holding the
frame's time to receiving the batch), then the median, 95th percentile and maximum
over all frames. Without --realtime espeak-ng is far faster than speech, so the whole
utterance is sent at once and the latency is mostly the server's decoding time.

PYTHONPATH must hold the generated stubs and clients/python (docs/python-client.md).

Exit status: 0 on success, 1 when the server answers with an error (printed as
"listen.py: CODE: details"), 2 for bad arguments, 3 when espeak-ng fails or is missing.
"""

from __future__ import annotations

import argparse
import os
import shutil
import struct
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir))


class SpeechError(Exception):
    """espeak-ng is missing, failed, or wrote something that is not 16-bit PCM WAV."""


def read_exact(pipe, size: int) -> bytes:
    data = b""
    while len(data) < size:
        piece = os.read(pipe.fileno(), size - len(data))
        if not piece:
            raise SpeechError(f"espeak-ng's WAV ended after {len(data)} of {size} header bytes")
        data += piece
    return data


def read_wav_header(pipe):
    """Reads a WAV header from `pipe` up to the start of its samples; returns (rate_hz, channels).
    A streaming writer's data size (espeak-ng writes 0x7ffff000) is ignored: the samples run to
    the end of the pipe."""
    riff = read_exact(pipe, 12)
    if riff[:4] != b"RIFF" or riff[8:12] != b"WAVE":
        raise SpeechError("espeak-ng's output is not a RIFF/WAVE file")
    fmt = None
    while True:
        chunk_id, size = struct.unpack("<4sI", read_exact(pipe, 8))
        if chunk_id == b"data":
            break
        body = read_exact(pipe, size + (size & 1))
        if chunk_id == b"fmt ":
            fmt = struct.unpack("<HHIIHH", body[:16])
    if fmt is None:
        raise SpeechError("espeak-ng's WAV has no fmt chunk before its data")
    tag, channels, rate_hz, _, _, bits = fmt
    if tag != 1 or bits != 16:
        raise SpeechError(f"espeak-ng's WAV is format {tag} with {bits}-bit samples, not 16-bit PCM")
    return rate_hz, channels


def pcm_pieces(pipe, piece_bytes: int, realtime: bool, bytes_per_second: int):
    """The samples from `pipe`: as they come (at most piece_bytes at a time), or, realtime,
    in pieces of exactly piece_bytes, piece k no earlier than k * piece duration after the first."""
    if not realtime:
        while True:
            piece = os.read(pipe.fileno(), piece_bytes)
            if not piece:
                return
            yield piece
    start, sent, pending = None, 0, b""
    while True:
        data = os.read(pipe.fileno(), piece_bytes)
        pending += data
        while len(pending) >= piece_bytes or (not data and pending):
            piece, pending = pending[:piece_bytes], pending[piece_bytes:]
            if start is None:
                start = time.monotonic()
            delay = start + sent / bytes_per_second - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            yield piece
            sent += len(piece)
        if not data:
            return


def percentile(sorted_values, fraction: float) -> float:
    return sorted_values[min(len(sorted_values) - 1, int(fraction * len(sorted_values)))]


def parse_arguments(argv=None):
    parser = argparse.ArgumentParser(
        prog="listen.py",
        description="Speak TEXT with espeak-ng and pipe the audio into lipsyncd's Listen as it is "
        "synthesised; print the latency of each frame batch at the end.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="example: listen.py --session demo --realtime \"Papa bought five more big maps.\"",
    )
    parser.add_argument("text", nargs="+", help="the text to speak (words are joined with spaces)")
    parser.add_argument("--server", default="127.0.0.1:50051", help="lipsyncd address (default %(default)s)")
    parser.add_argument("--session", default="", help="publish the frames (and audio) under this session name")
    parser.add_argument("--voice", default="en-us",
                        help="espeak-ng voice, also sent as Listen's voice: English only (default %(default)s)")
    parser.add_argument("--speed", type=int, default=0, help="espeak-ng's words per minute (default: its own, 175)")
    parser.add_argument("--piece-ms", type=int, default=20, help="audio per message, 5..1000 ms (default %(default)s)")
    parser.add_argument("--realtime", action="store_true",
                        help="send the audio at the pace it would be spoken (default: as fast as espeak-ng writes it)")
    parser.add_argument("--latency-ms", type=int, help="the server's latency budget, 100..2000 (default: its 200)")
    parser.add_argument("--no-transcript", action="store_true",
                        help="let the server recognise the words instead of sending TEXT as the transcript")
    parser.add_argument("--fps", type=int, default=0, help="frame rate, 1..240 (default: the server's, 30)")
    parser.add_argument("--timeout", type=float, default=60.0, help="deadline of the call in seconds (default %(default)s)")
    arguments = parser.parse_args(argv)
    if not 5 <= arguments.piece_ms <= 1000:
        parser.error("--piece-ms must be 5 to 1000")
    return arguments


def main(argv=None) -> int:
    arguments = parse_arguments(argv)
    text = " ".join(arguments.text)
    espeak = shutil.which("espeak-ng")
    if espeak is None:
        print("listen.py: espeak-ng not found: apt-get install espeak-ng", file=sys.stderr)
        return 3
    command = [espeak, "--stdout", "-v", arguments.voice]
    if arguments.speed:
        command += ["-s", str(arguments.speed)]
    synthesiser = subprocess.Popen(command + [text], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        return listen(arguments, text, synthesiser)
    finally:
        if synthesiser.poll() is None:
            synthesiser.kill()
        synthesiser.wait()
        synthesiser.stdout.close()
        synthesiser.stderr.close()


def listen(arguments, text: str, synthesiser) -> int:
    import grpc  # imported here so that --help works without grpc installed

    from lipsync_client import Client

    try:
        rate_hz, channels = read_wav_header(synthesiser.stdout)
    except SpeechError as error:
        print(f"listen.py: {error}; espeak-ng said: {synthesiser.stderr.read().decode(errors='replace')}",
              file=sys.stderr)
        return 3
    bytes_per_second = rate_hz * channels * 2
    piece_bytes = max(2 * channels, bytes_per_second * arguments.piece_ms // 1000 // (2 * channels) * 2 * channels)
    pieces = pcm_pieces(synthesiser.stdout, piece_bytes, arguments.realtime, bytes_per_second)
    options = {"sample_rate_hz": rate_hz, "audio_channels": channels, "voice": arguments.voice,
               "session": arguments.session, "fps": arguments.fps}
    if not arguments.no_transcript:
        options["transcript"] = text
    if arguments.latency_ms is not None:
        options["latency_ms"] = arguments.latency_ms
    frames = []
    try:
        with Client(arguments.server, timeout=arguments.timeout) as client:
            stream = client.listen(pieces, **options)
            for frame in stream:
                if not frames:
                    print(f"# model {stream.header.model}, {stream.header.fps} fps, audio {rate_hz} Hz, "
                          f"budget {stream.header.release_delay_us // 1000} ms"
                          + (f", session {stream.header.session}" if stream.header.session else ""))
                frames.append(frame)
    except grpc.RpcError as error:
        print(f"listen.py: {error.code().name}: {error.details()}", file=sys.stderr)
        return 1
    if synthesiser.wait() != 0:
        print(f"listen.py: espeak-ng failed: {synthesiser.stderr.read().decode(errors='replace')}", file=sys.stderr)
        return 3

    if not frames:
        print("# no frames: the server heard no speech", file=sys.stderr)
        return 0
    print("first_frame\tframes\tfirst_t_us\tlast_t_us\tlatency_first_ms\tlatency_last_ms\trelease_lag_ms")
    for arrival in stream.arrivals:
        first = stream.latency_s(frames[arrival.first_index])
        last = stream.latency_s(frames[arrival.first_index + arrival.count - 1])
        print(f"{arrival.first_index}\t{arrival.count}\t{arrival.first_t_us}\t{arrival.last_t_us}\t"
              f"{first * 1000:.1f}\t{last * 1000:.1f}\t{arrival.release_lag_us / 1000:.1f}")
    latencies = sorted(stream.latency_s(frame) * 1000 for frame in frames)
    summary = stream.summary
    print(f"# {summary.frames} frames, {summary.phonemes} phonemes, {summary.duration_us} µs of speech "
          f"in {len(stream.arrivals)} batches; latency per frame (ms): median {percentile(latencies, 0.5):.1f}, "
          f"95th percentile {percentile(latencies, 0.95):.1f}, max {latencies[-1]:.1f}")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except BrokenPipeError:  # the reader went away (e.g. piped into head)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(1)
