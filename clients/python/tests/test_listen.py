"""Client.listen and examples/listen.py against the REAL lipsyncd: speech in, frames out.

Environment (as test_live_server):
    LIPSYNCD        path of the lipsyncd binary (ctest sets it: $<TARGET_FILE:lipsyncd>)
    PYTHONPATH      <build>/clients/python/generated:<source>/clients/python
    LIPSYNC_PYTHON  interpreter for the example (default: this one)

The speech is flite's (`flite -voice slt`, 16 kHz mono), sent as 20 ms pieces of raw PCM
at the pace it would be spoken. A missing or unstartable server, or a missing flite,
FAILS these tests; only the example's test skips without espeak-ng (Debian package
espeak-ng, which the example pipes from).

Run by hand (from clients/python/tests):
    LIPSYNCD=<build>/server/lipsyncd PYTHONPATH=<build>/clients/python/generated:.. \\
        /usr/bin/python3 -m unittest -v test_listen
"""

import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import unittest
import wave

import grpc

from lipsync_client import Words
from lipsyncd_test_server import RPC_TIMEOUT_S, LipsyncdTestCase

HERE = os.path.dirname(os.path.abspath(__file__))
EXAMPLE = os.path.join(HERE, os.pardir, "examples", "listen.py")
TEXT = "Papa bought five more big maps."
PIECE_MS = 20
EXAMPLE_TIMEOUT_S = 60.0


def flite_wav(text, path):
    """Speaks `text` with flite's slt voice into the WAV file `path`; returns (pcm, rate_hz, channels)."""
    if shutil.which("flite") is None:
        raise AssertionError("flite not found: apt-get install flite")
    subprocess.run(["flite", "-voice", "slt", "-t", text, "-o", path], check=True, timeout=30,
                   capture_output=True)
    with wave.open(path, "rb") as wav:
        if wav.getsampwidth() != 2:
            raise AssertionError(f"flite wrote {8 * wav.getsampwidth()}-bit samples, not 16-bit")
        return wav.readframes(wav.getnframes()), wav.getframerate(), wav.getnchannels()


class ListenTest(LipsyncdTestCase):
    @classmethod
    def set_up_class(cls):
        with tempfile.TemporaryDirectory() as directory:
            cls.pcm, cls.rate_hz, cls.channels = flite_wav(TEXT, os.path.join(directory, "speech.wav"))

    def spoken_pieces(self, first_frame, waits):
        """The speech in PIECE_MS pieces, piece k leaving k x PIECE_MS after the first (a speaker's
        pace); the second half waits (up to RPC_TIMEOUT_S / 2, noted in `waits`) for the event
        `first_frame`, so that frames must come back while the audio is still being sent."""
        piece_bytes = self.rate_hz * PIECE_MS // 1000 * 2 * self.channels
        half = len(self.pcm) // 2 // piece_bytes * piece_bytes
        start = time.monotonic()
        for k, offset in enumerate(range(0, len(self.pcm), piece_bytes)):
            if offset == half:
                waited = time.monotonic()
                waits.append((first_frame.wait(timeout=RPC_TIMEOUT_S / 2), time.monotonic() - waited))
                start += waits[-1][1]
            delay = start + k * PIECE_MS / 1000 - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            yield self.pcm[offset:offset + piece_bytes]

    def test_spoken_pieces_give_a_header_then_frames_covering_the_audio_then_a_summary(self):
        duration_us = len(self.pcm) // (2 * self.channels) * 1_000_000 // self.rate_hz
        first_frame, waits = threading.Event(), []
        stream = self.client.listen(self.spoken_pieces(first_frame, waits), sample_rate_hz=self.rate_hz,
                                    audio_channels=self.channels, transcript=TEXT, latency_ms=300)
        frames = []
        for frame in stream:
            first_frame.set()
            self.assertIsNotNone(stream.header, f"frame {frame.index} arrived before the track header")
            self.assertIsNone(stream.summary, f"frame {frame.index} arrived after the summary")
            frames.append(frame)
        self.assertIsNotNone(stream.summary, "the stream ended without a summary")

        header = stream.header
        self.assertEqual(header.release_delay_us, 300_000, "latency_ms=300 did not reach the server")
        self.assertIn("jaw_rotation", list(header.channels))
        self.assertEqual(len(header.arkit_names), 52)
        self.assertTrue(frames, "no frames")
        self.assertEqual([f.index for f in frames], list(range(len(frames))))
        times = [f.t_us for f in frames]
        self.assertTrue(all(isinstance(t, int) and not isinstance(t, bool) for t in times), "times are not integers")
        self.assertTrue(all(a < b for a, b in zip(times, times[1:])), f"times not strictly increasing: {times}")
        period_us = 1_000_000 // header.fps
        self.assertLessEqual(times[0], period_us, "the frames start late")
        self.assertGreaterEqual(times[-1], duration_us - period_us, f"the frames stop before the audio's end ({duration_us} µs)")
        self.assertLessEqual(times[-1], duration_us + period_us, f"frames after the audio's end ({duration_us} µs)")
        self.assertTrue(all(list(f.channels) == list(header.channels) and len(f.arkit) == 52 for f in frames),
                        "frames not in the header's shape")
        self.assertEqual(stream.summary.frames, len(frames))
        self.assertEqual(stream.summary.duration_us, duration_us)
        self.assertGreater(stream.summary.phonemes, 10, "too few phonemes for a 2-second sentence")

        # Live: frames come back while the speech is still being sent (the request side is read
        # lazily, and the server does not wait for `end`).
        self.assertEqual(len(waits), 1)
        self.assertTrue(waits[0][0], f"no frame came back within {waits[0][1]:.1f} s of the first half of the audio")
        self.assertLess(stream.arrivals[0].received_s, stream.sent_at(duration_us),
                        "the first frames arrived only after the last piece of audio was sent")
        self.assertEqual(sum(a.count for a in stream.arrivals), len(frames))
        self.assertTrue(all(stream.latency_s(f) is not None for f in frames))

    def test_words_among_the_pieces_grow_an_empty_transcript_and_reach_the_recogniser(self):
        # The sentence's words come as Words: the first three before any audio, the rest timed
        # (at made-up but ordered times) a third of the way in. Speech that outlasted the words
        # would be noted in the summary ("after the transcript's last word"): none is.
        piece_bytes = self.rate_hz * PIECE_MS // 1000 * 2 * self.channels
        words = TEXT.rstrip(".").split()

        def pieces():
            yield Words(text=" ".join(words[:3]))
            for k, offset in enumerate(range(0, len(self.pcm), piece_bytes)):
                if k == 30:
                    yield Words(timed=[(word, 600_000 + 150_000 * i) for i, word in enumerate(words[3:])])
                yield self.pcm[offset:offset + piece_bytes]

        stream = self.client.listen(pieces(), sample_rate_hz=self.rate_hz, audio_channels=self.channels,
                                    transcript="")
        frames = stream.collect()
        self.assertTrue(frames, "no frames")
        self.assertIsNotNone(stream.summary)
        self.assertEqual(list(stream.summary.notes), [])
        self.assertGreater(stream.summary.phonemes, 10)

    def test_words_on_a_stream_without_a_transcript_are_invalid_argument_naming_them(self):
        with self.assertRaises(grpc.RpcError) as caught:
            self.client.listen([self.pcm[:640], Words(text="papa")], sample_rate_hz=self.rate_hz).collect()
        self.assertEqual(caught.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("words: the settings have no transcript", caught.exception.details())

    def test_bad_sample_rate_is_invalid_argument_naming_the_field(self):
        with self.assertRaises(grpc.RpcError) as caught:
            self.client.listen([self.pcm], sample_rate_hz=4000).collect()
        self.assertEqual(caught.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("settings.sample_rate_hz", caught.exception.details())

    def test_a_piece_that_is_not_bytes_raises_type_error_naming_it(self):
        with self.assertRaises(TypeError) as caught:
            self.client.listen([self.pcm[:640], "not audio"], sample_rate_hz=self.rate_hz).collect()
        self.assertIn("audio piece 1", str(caught.exception))

    @unittest.skipUnless(shutil.which("espeak-ng"), "espeak-ng not installed (apt-get install espeak-ng)")
    def test_example_pipes_espeak_ng_and_prints_latency_per_batch(self):
        python = os.environ.get("LIPSYNC_PYTHON", sys.executable)
        result = subprocess.run(
            [python, EXAMPLE, "--server", self.address, "--timeout", str(RPC_TIMEOUT_S), TEXT],
            capture_output=True, text=True, timeout=EXAMPLE_TIMEOUT_S, check=False,
        )
        self.assertEqual(result.returncode, 0, f"listen.py failed:\n{result.stdout}\n{result.stderr}")
        lines = result.stdout.splitlines()
        self.assertTrue(lines[0].startswith("# model "), result.stdout)
        self.assertTrue(lines[1].startswith("first_frame\tframes\t"), result.stdout)
        batches = [line.split("\t") for line in lines[2:-1]]
        self.assertTrue(batches and all(len(cells) == 7 for cells in batches), result.stdout)
        self.assertEqual(int(batches[0][0]), 0)
        self.assertRegex(lines[-1], r"^# (\d+) frames, .* latency per frame \(ms\): median [0-9.]+, ", result.stdout)
        frames = int(re.match(r"# (\d+) frames", lines[-1]).group(1))
        self.assertEqual(sum(int(cells[1]) for cells in batches), frames)


if __name__ == "__main__":
    unittest.main()
