"""The Python client and examples/speak.py end to end against the REAL lipsyncd.

Environment:
    LIPSYNCD        path of the lipsyncd binary (ctest sets it: $<TARGET_FILE:lipsyncd>)
    PYTHONPATH      <build>/clients/python/generated:<source>/clients/python
    LIPSYNC_PYTHON  interpreter for the example (default: this one)

A missing or unstartable server FAILS these tests (never skips). Every RPC has a
deadline and every subprocess a timeout, so nothing hangs.

Run by hand (from clients/python/tests):
    LIPSYNCD=<build>/server/lipsyncd PYTHONPATH=<build>/clients/python/generated:.. \\
        /usr/bin/python3 -m unittest -v test_live_server
"""

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
import unittest
import wave

import grpc

from lipsync.v1 import lipsync_pb2
from lipsync_client import tts
from lipsyncd_test_server import RPC_TIMEOUT_S, LipsyncdTestCase

HERE = os.path.dirname(os.path.abspath(__file__))
SPEAK = os.path.join(HERE, os.pardir, "examples", "speak.py")
TEXT = "Peter picked a peck of pickled peppers."
EXAMPLE_TIMEOUT_S = 120.0


class LiveServerTest(LipsyncdTestCase):
    @classmethod
    def set_up_class(cls):
        cls.phonemes = tts.flite_phonemes(TEXT)

    # -- helpers --------------------------------------------------------------

    def assert_frames_equal(self, expected, actual, what):
        self.assertEqual(len(expected), len(actual), f"{what}: frame counts differ")
        for a, b in zip(expected, actual):
            self.assertEqual((a.index, a.t_us, a.kind), (b.index, b.t_us, b.kind), what)
            self.assertEqual(a.channels, b.channels, f"{what}: channels of frame {a.index}")
            self.assertEqual(a.arkit, b.arkit, f"{what}: ARKit weights of frame {a.index}")

    def assert_times_strictly_increasing_integers(self, times):
        self.assertTrue(times, "no frames")
        for t in times:
            self.assertTrue(isinstance(t, int) and not isinstance(t, bool), f"time {t!r} is not an integer")
        for previous, current in zip(times, times[1:]):
            self.assertLess(previous, current, "frame times are not strictly increasing")

    # -- tests ----------------------------------------------------------------

    def test_list_models(self):
        models = self.client.list_models()
        self.assertTrue(models, "ListModels returned no model")
        self.assertEqual(sum(1 for m in models if m.is_default), 1, "exactly one default model")
        default = self.client.get_model("")
        self.assertTrue(default.is_default)
        self.assertIn("radio", list(default.phone_sets))
        self.assertIn("jaw_rotation", [c.name for c in default.channels])
        self.assertEqual(len(default.arkit_names), 52)

    def test_example_end_to_end_with_flite(self):
        with tempfile.TemporaryDirectory() as directory:
            out = os.path.join(directory, "track.json")
            python = os.environ.get("LIPSYNC_PYTHON", sys.executable)
            result = subprocess.run(
                [python, SPEAK, "--server", self.address, "--frontend", "flite",
                 "--chunk-size", "3", "--timeout", str(RPC_TIMEOUT_S), "--json", out, TEXT],
                capture_output=True, text=True, timeout=EXAMPLE_TIMEOUT_S, check=False,
            )
            self.assertEqual(result.returncode, 0, f"speak.py failed:\n{result.stdout}\n{result.stderr}")
            with open(out, encoding="utf-8") as handle:
                document = json.load(handle)

        phonemes = [tts.TimedPhoneme(p["label"], p["start_us"], p["end_us"]) for p in document["phonemes"]]
        self.assertEqual(phonemes, self.phonemes, "the example's flite phonemes")
        frames = document["frames"]
        self.assertGreater(len(frames), 20, "too few frames for a 2-second sentence")
        self.assertEqual([f["index"] for f in frames], list(range(len(frames))))
        times = [f["t_us"] for f in frames]
        self.assert_times_strictly_increasing_integers(times)
        self.assertEqual(document["summary"]["frames"], len(frames))
        self.assertEqual(document["summary"]["phonemes"], len(phonemes))
        self.assertEqual(document["summary"]["duration_us"], phonemes[-1].end_us)
        self.assertLessEqual(times[-1], phonemes[-1].end_us)
        header = document["header"]
        self.assertIn("jaw_rotation", header["channels"])
        self.assertEqual(len(header["arkit_names"]), 52)
        for frame in frames:
            self.assertEqual(list(frame["channels"]), header["channels"])
            self.assertEqual(list(frame["arkit"]), header["arkit_names"])

        # Every /p/ is a closure: a closure_start key frame exactly where it starts,
        # a closure_end key frame inside it (where the closure part ends).
        p_segments = [p for p in phonemes if p.label == "p"]
        self.assertGreaterEqual(len(p_segments), 6)
        kind_at = {f["t_us"]: f["kind"] for f in frames}
        for p in p_segments:
            self.assertEqual(kind_at.get(p.start_us), "closure_start", f"closure_start at /p/ {p}")
            ends = [f for f in frames if f["kind"] == "closure_end" and p.start_us < f["t_us"] < p.end_us]
            self.assertEqual(len(ends), 1, f"one closure_end inside /p/ {p}")
            inside = [f for f in frames if p.start_us < f["t_us"] < ends[0]["t_us"]]
            self.assertEqual(inside, [], f"no frames inside the closure of /p/ {p}")

        # The streamed frames (chunks of 3) equal an offline Render of the same phonemes.
        rendered = self.client.render(phonemes, phone_set="radio")
        self.assertEqual(len(rendered.frames), len(frames))
        for r, f in zip(rendered.frames, frames):
            self.assertEqual((r.t_us, r.kind), (f["t_us"], f["kind"]))
            self.assertEqual(r.channels, f["channels"], f"channels of frame {r.index}")
            self.assertEqual(r.arkit, f["arkit"], f"ARKit weights of frame {r.index}")

    def test_animate_equals_render(self):
        rendered = self.client.render(self.phonemes, phone_set="radio")
        self.assert_times_strictly_increasing_integers([f.t_us for f in rendered.frames])
        for chunk_size in (1, 5, len(self.phonemes)):
            with self.subTest(chunk_size=chunk_size):
                streamed = self.client.animate(self.phonemes, phone_set="radio", chunk_size=chunk_size).collect()
                self.assertEqual(list(streamed.header.channels), list(rendered.header.channels))
                self.assertEqual(list(streamed.header.arkit_names), list(rendered.header.arkit_names))
                self.assertEqual(streamed.header.lookahead, 7)
                self.assertEqual(streamed.summary, rendered.summary)
                self.assert_frames_equal(rendered.frames, streamed.frames, f"Animate (chunks of {chunk_size})")
        # Chunks given explicitly, as a streaming TTS front-end would yield them.
        chunks = (self.phonemes[i:i + 4] for i in range(0, len(self.phonemes), 4))
        streamed = self.client.animate(chunks, phone_set="radio").collect()
        self.assert_frames_equal(rendered.frames, streamed.frames, "Animate (generator of chunks)")

    def test_settings_reach_the_server(self):
        track = self.client.render(self.phonemes, phone_set="radio", fps=60, arkit=True)
        self.assertEqual(track.header.fps, 60)
        self.assertEqual(list(track.header.channels), [])
        self.assertEqual(len(track.header.arkit_names), 52)
        self.assertTrue(all(f.channels == {} and len(f.arkit) == 52 for f in track.frames))
        fixed = self.client.render(self.phonemes, phone_set="radio", fixed_rate=True)
        self.assertEqual({f.kind for f in fixed.frames}, {"uniform"})

    def test_mesh_settings_reach_the_server_and_the_fast_solve_is_named_in_the_header(self):
        full = self.client.render(self.phonemes, phone_set="radio", mesh=True, mesh_subdivision=0)
        fast = self.client.render(self.phonemes, phone_set="radio", mesh=True, mesh_subdivision=0, mesh_solve="fast")
        self.assertEqual(full.header.mesh.subdivision, 0)
        self.assertEqual(full.header.mesh.solve, lipsync_pb2.MESH_SOLVE_FULL)
        self.assertEqual(fast.header.mesh.solve, lipsync_pb2.MESH_SOLVE_FAST)
        width = full.header.mesh.vertex_count * 3
        self.assertTrue(width > 0 and all(len(f.mesh) == width for f in full.frames + fast.frames))
        self.assertEqual([f.channels for f in fast.frames], [f.channels for f in full.frames])
        self.assertNotEqual([f.mesh for f in fast.frames], [f.mesh for f in full.frames])
        with self.assertRaises(ValueError):
            self.client.render(self.phonemes, phone_set="radio", mesh=True, mesh_solve="quick")

    def test_visemes_stream_equal_render_with_names_weights_and_events(self):
        rendered = self.client.render(self.phonemes, phone_set="radio", visemes="rhubarb", rhubarb_extended_shapes="GX")
        self.assertEqual(list(rendered.header.viseme_names), ["A", "B", "C", "D", "E", "F", "G", "H", "X"])
        self.assertTrue(all(len(f.visemes) == 9 and abs(sum(f.visemes.values()) - 1) < 1e-4 and f.visemes["H"] == 0
                            for f in rendered.frames))
        events = rendered.viseme_events()
        self.assertEqual(events[0], (max(rendered.frames[0].visemes, key=rendered.frames[0].visemes.get),
                                     rendered.frames[0].t_us))
        self.assertIn("A", {name for name, _ in events})  # the closures of "Peter picked a peck ..."
        streamed = self.client.animate(self.phonemes, phone_set="radio", visemes="rhubarb",
                                       rhubarb_extended_shapes="GX", chunk_size=3).collect()
        self.assertEqual([f.visemes for f in streamed.frames], [f.visemes for f in rendered.frames])
        self.assertEqual(streamed.viseme_events(), events)
        plain = self.client.render(self.phonemes, phone_set="radio")
        self.assertEqual(list(plain.header.viseme_names), [])
        self.assertTrue(all(f.visemes is None and f.viseme_event is None for f in plain.frames))

    def test_bad_input_is_invalid_argument(self):
        overlapping = [("pau", 0, 100000), ("p", 50000, 150000)]
        with self.assertRaises(grpc.RpcError) as caught:
            self.client.render(overlapping, phone_set="radio")
        self.assertEqual(caught.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertTrue(caught.exception.details())
        with self.assertRaises(grpc.RpcError) as caught:
            self.client.animate([("pau", 0, 100000), ("no-such-phone", 100000, 200000)],
                                phone_set="radio").collect()
        self.assertEqual(caught.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("no-such-phone", caught.exception.details())

    def test_subscribe_follows_a_session(self):
        session = f"python-live-test-{os.getpid()}"
        release = threading.Event()
        first, rest = self.phonemes[:12], self.phonemes[12:]

        def chunks():  # the second half waits until the subscriber has joined
            yield first
            release.wait(timeout=RPC_TIMEOUT_S)
            yield rest

        producer = self.client.animate(chunks(), phone_set="radio", session=session, chunk_size=4)
        produced = iter(producer)
        produced_frames = [next(produced)]  # the session exists once frames flow

        subscriber = self.client.subscribe(session, from_beginning=True)
        followed, failure, joined = [], [], threading.Event()

        def follow():
            try:
                for frame in subscriber:
                    followed.append(frame)
                    joined.set()
            except grpc.RpcError as error:
                failure.append(error)
            finally:
                joined.set()

        follower = threading.Thread(target=follow, daemon=True)
        follower.start()
        self.assertTrue(joined.wait(timeout=RPC_TIMEOUT_S), "the subscriber got no frame")
        release.set()
        produced_frames.extend(produced)
        follower.join(timeout=RPC_TIMEOUT_S)
        self.assertFalse(follower.is_alive(), "the subscription did not end after the producer")
        self.assertEqual(failure, [], "Subscribe failed")
        self.assertEqual(subscriber.header.session, session)
        self.assertEqual(producer.header.session, session)
        self.assertEqual(subscriber.summary, producer.summary)
        self.assert_frames_equal(produced_frames, followed, "Subscribe (from the beginning)")

        with self.assertRaises(grpc.RpcError) as caught:
            self.client.subscribe(f"{session}-absent").collect()
        self.assertEqual(caught.exception.code(), grpc.StatusCode.NOT_FOUND)

    def test_speak_returns_audio_and_the_frames_of_its_phonemes(self):
        session = f"python-speak-test-{os.getpid()}"
        speech = self.client.speak("Papa parked the car.", words_per_minute=200, session=session)
        header = speech.header
        self.assertEqual((header.sample_rate_hz, header.channels, header.words_per_minute), (22050, 1, 200))
        self.assertEqual(len(speech.pcm), header.sample_count * 2)
        self.assertEqual(header.audio_duration_us, header.sample_count * 1_000_000 // header.sample_rate_hz)
        self.assertTrue(any(s != 0 for s in speech.samples()), "the audio is silent")
        times = [frame.t_us for frame in speech.track.frames]
        self.assert_times_strictly_increasing_integers(times)
        self.assertGreaterEqual(times[-1], header.audio_duration_us, "the track ends before the audio")
        # The frames are those of the phonemes the header reports, rendered offline by the server.
        rendered = self.client.render(list(header.phonemes), phone_set="espeak")
        self.assert_frames_equal(rendered.frames, speech.track.frames, "Speak against Render")
        # The session replays the same frames to a subscriber that joins after the call.
        followed = self.client.subscribe(session).collect()
        self.assert_frames_equal(speech.track.frames, followed.frames, "Subscribe to a Speak session")
        with tempfile.TemporaryDirectory() as directory:
            path = os.path.join(directory, "speech.wav")
            speech.write_wav(path)
            with wave.open(path, "rb") as wav:
                self.assertEqual((wav.getframerate(), wav.getnchannels()), (22050, 1))
                self.assertEqual(wav.readframes(wav.getnframes()), speech.pcm)

    def test_speak_refuses_an_unknown_voice_naming_it(self):
        with self.assertRaises(grpc.RpcError) as caught:
            self.client.speak("Hello.", voice="no-such-voice")
        self.assertEqual(caught.exception.code(), grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("voice:", caught.exception.details())
        self.assertIn("no-such-voice", caught.exception.details())


if __name__ == "__main__":
    unittest.main()
