"""The add-on's track reader (clients/blender/lipsync_blender/track.py) on what the CLI writes.

No Blender needed: track.py is plain Python. The built `lipsync` renders real speech (Festival's
and flite's recorded timings, tests/data/closures) at several frame rates, as JSON and as Live
Link Face CSV; the CSV read at its rate must give the JSON's frames: the same count, times
within half of the timecode's 1/1000 frame, the same ARKit weights (as text, the shortest
float32 spelling, so equal floats). Read at twice its rate or more, or at half of it, the CSV is
refused with a message that says to set the rate.

Usage: LIPSYNC=<build>/clients/cli/lipsync SOURCE_DIR=<source> python3 track_reader_test.py
"""

import importlib.util
import json
import os
import subprocess
import sys
import unittest

SOURCE_DIR = os.environ.get("SOURCE_DIR", os.path.join(os.path.dirname(__file__), "../../.."))
LIPSYNC = os.environ.get("LIPSYNC", "build/clients/cli/lipsync")
SOURCES = ["festival_1.lab", "festival_3.lab", "festival_5.lab",
           "flite_2.psdur", "flite_4.psdur", "flite_6.psdur"]
RATES = (12, 24, 30, 60, 120)


def load_track_module():
    path = os.path.join(SOURCE_DIR, "clients/blender/lipsync_blender/track.py")
    spec = importlib.util.spec_from_file_location("lipsync_blender_track", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


track = load_track_module()


def render(source, fps, fmt):
    extra = ["--phone-set", "radio"] if source.endswith(".psdur") else []
    result = subprocess.run([LIPSYNC, "render", os.path.join(SOURCE_DIR, "tests/data/closures", source),
                             *extra, "--format", fmt, "--fps", str(fps)],
                            capture_output=True, text=True, timeout=60)
    if result.returncode != 0:
        raise AssertionError(f"lipsync render {source} --fps {fps} --format {fmt}: {result.stderr}")
    return result.stdout


class LiveLinkFaceCsv(unittest.TestCase):
    def test_csv_at_its_rate_gives_the_json_tracks_frames(self):
        for source in SOURCES:
            for fps in RATES:
                with self.subTest(source=source, fps=fps):
                    document = json.loads(render(source, fps, "json"))
                    text = render(source, fps, "arkit-csv")
                    csv = track.parse_csv_track(text, source, fps)
                    frames = document["frames"]
                    self.assertEqual(len(csv.times_us), len(frames))
                    tolerance_us = 1e6 / fps / 2000 + 0.5
                    worst = max(abs(a - f["t_us"]) for a, f in zip(csv.times_us, frames))
                    self.assertLessEqual(worst, tolerance_us)
                    for k, name in enumerate(document["arkit_names"]):
                        self.assertEqual(csv.arkit[name], [float(f["arkit"][k]) for f in frames], name)
                    for fps_wrong in (fps * 2, fps * 2 + 1, fps // 2):
                        if 1 <= fps_wrong <= 240:
                            with self.assertRaisesRegex(track.TrackError, "set the CSV frame rate"):
                                track.parse_csv_track(text, source, fps_wrong)


if __name__ == "__main__":
    unittest.main(verbosity=2)
