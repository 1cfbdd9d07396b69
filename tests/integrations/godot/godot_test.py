"""The Godot add-on (clients/godot/addons/lipsync) inside real Godot: Debian's godot3-server 3.2.3,
the headless runtime, running the GDScript tests beside this file in a throw-away project that
holds the add-on. Nothing is stubbed: the tracks are rendered at test time by the built `lipsync`
from the real Festival and flite timings of tests/data/closures, and the live session comes from a
real lipsyncd (--http-listen on port 0) fed in real time by `lipsync stream`.

  * closures: at every closure key frame and open-vowel frame of four utterances the mesh's blend
    shapes equal the track's ARKit weights, and between frames their interpolation (test_player.gd);
  * audio: an AudioStreamPlayer's clock drives the face (pause freezes it, seek moves it);
  * bad_input: a track of another model (rendered with `lipsync model dump` renamed), a mesh
    without the shape keys, wrong mappings, a viseme file, a phoneme file, flite's WAV, bytes that
    are not UTF-8: refused, push_error saying what to do (and no line of Godot's own before it),
    the scene untouched;
  * mapping: a partial mapping overrides the names it lists and the other ARKit names drive their
    namesakes (the Blender add-on's rule);
  * live: a lipsyncd session followed over the viewer's WebSocket with the media-clock anchor, the
    follower started before the session (it asks again until the session exists); a session that
    never starts is reported after live_wait_ms;
  * listen: an AudioStreamPlayer plays flite's WAV of "Papa bought five more big maps." and the
    player sends its samples to lipsyncd's /listen as they play (with the words), following the
    session: closed at the /p b m/ middles and open at the open vowels of lipsyncd's offline render
    of the same WAV, drawn on the audio clock (test_listen.gd); meanwhile, on the same lipsyncd, the
    players it cannot hear (no stream, Ogg Vorbis, IMA-ADPCM, no samples) are refused with what to
    do and nothing sent, and a voice at a rate lipsyncd refuses is reported with its refusal;
  * no_server: following a viewer address where nothing listens reports it; bad_address: an address
    that is not a viewer's is answered with the http://HOST:PORT/view address lipsyncd prints.

Usage: godot_test.py LIPSYNC LIPSYNCD SOURCE_DIR. Exits 77 (skipped) without godot3-server.
"""

import json
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import unittest

LIPSYNC, LIPSYNCD, SOURCE_DIR = sys.argv[1:4] if len(sys.argv) >= 4 else \
    ("build/clients/cli/lipsync", "build/server/lipsyncd", ".")
GODOT = shutil.which("godot3-server")
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "support"))
from listening_address import ServerProcess  # noqa: E402
CLOSURES = os.path.join(SOURCE_DIR, "tests", "data", "closures")
TRACK_INPUTS = ["flite_1.psdur", "festival_2.lab", "flite_fast_3.psdur", "aligned_festival_5.TextGrid"]


def free_port():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


class GodotAddOn(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.mkdtemp(prefix="lipsync-godot-")
        cls.project = os.path.join(cls.workdir, "project")
        os.makedirs(cls.project)
        with open(os.path.join(cls.project, "project.godot"), "w") as project:
            project.write('config_version=4\n\n[application]\n\nconfig/name="lipsync add-on test"\n')
        shutil.copytree(os.path.join(SOURCE_DIR, "clients", "godot", "addons"), os.path.join(cls.project, "addons"))
        for script in ("checking_tree.gd", "face_fixture.gd", "test_player.gd", "test_live.gd", "test_listen.gd"):
            shutil.copy(os.path.join(HERE, script), cls.project)
        cls.tracks = []
        for name in TRACK_INPUTS:
            out = os.path.join(cls.workdir, name + ".json")
            subprocess.run([LIPSYNC, "render", os.path.join(CLOSURES, name), "-o", out], check=True)
            cls.tracks.append(out)
        # A track of another model: the default model under another name.
        model = json.loads(subprocess.run([LIPSYNC, "model", "dump"], check=True, capture_output=True,
                                          text=True).stdout)
        model["name"] = "other-rig"
        with open(os.path.join(cls.workdir, "other.json"), "w") as other:
            json.dump(model, other)
        cls.other_track = os.path.join(cls.workdir, "other_track.json")
        subprocess.run([LIPSYNC, "render", os.path.join(CLOSURES, "flite_1.psdur"), "--model",
                        os.path.join(cls.workdir, "other.json"), "-o", cls.other_track], check=True)
        cls.visemes = os.path.join(cls.workdir, "visemes.json")
        subprocess.run([LIPSYNC, "render", os.path.join(CLOSURES, "flite_1.psdur"), "--format", "visemes-oculus",
                        "-o", cls.visemes], check=True)
        # The speech itself, given where the track goes.
        cls.wav = os.path.join(cls.workdir, "papa.wav")
        subprocess.run(["flite", "-voice", "slt", "-t", "Papa bought five more big maps.", "-o", cls.wav], check=True)
        cls.text = "Papa bought five more big maps."
        cls.wav_track = os.path.join(cls.workdir, "papa_wav.json")
        subprocess.run([LIPSYNC, "render", cls.wav, "--text", cls.text, "-o", cls.wav_track], check=True)
        cls.ogg = os.path.join(cls.workdir, "papa.ogg")  # a stream Godot 3 gives no samples of
        subprocess.run(["ffmpeg", "-hide_banner", "-loglevel", "error", "-i", cls.wav, "-c:a", "libvorbis", cls.ogg],
                       check=True)
        cls.not_utf8 = os.path.join(cls.workdir, "latin1.json")
        with open(cls.not_utf8, "wb") as out:
            out.write('{"format": "lipsync-track", "text": "caf\u00e9"}\n'.encode("latin-1"))
        with open(cls.tracks[0], encoding="utf-8") as track:
            document = json.load(track)
        document["text"] = "Papa bought five more big maps. \u2014 caf\u00e9"
        cls.bom_track = os.path.join(cls.workdir, "bom_track.json")
        with open(cls.bom_track, "w", encoding="utf-8-sig") as out:
            json.dump(document, out, ensure_ascii=False)

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.workdir, ignore_errors=True)

    def environment(self, test, **env):
        """Godot's user and cache folders in the work folder; a locale Godot knows (not 'C')."""
        return dict(os.environ, HOME=self.workdir, XDG_DATA_HOME=os.path.join(self.workdir, "data"),
                    XDG_CONFIG_HOME=os.path.join(self.workdir, "config"),
                    XDG_CACHE_HOME=os.path.join(self.workdir, "cache"), LANG="en_US.UTF-8",
                    LIPSYNC_GODOT_TEST=test, **env)

    def godot(self, script, test, timeout=90, **env):
        return subprocess.run([GODOT, "--path", self.project, "-s", "res://" + script],
                              env=self.environment(test, **env), capture_output=True, text=True, timeout=timeout)

    def assertPassed(self, run):
        output = run.stdout + run.stderr
        for line in run.stdout.splitlines():
            if line.startswith(("ok:", "FAIL:")):
                print("  " + line, flush=True)
        self.assertEqual(run.returncode, 0, output[-6000:])
        self.assertNotIn("SCRIPT ERROR", output, output[-6000:])
        self.assertIn("ok:", run.stdout)

    def test_blend_shapes_equal_the_track_at_closures_and_open_vowels(self):
        run = self.godot("test_player.gd", "closures", LIPSYNC_TRACKS=";".join(self.tracks))
        self.assertPassed(run)
        self.assertNotIn("ERROR", run.stderr, run.stderr[-4000:])

    def test_the_audio_players_clock_drives_the_face(self):
        run = self.godot("test_player.gd", "audio", LIPSYNC_TRACKS=self.tracks[0])
        self.assertPassed(run)
        self.assertNotIn("ERROR", run.stderr, run.stderr[-4000:])

    def test_bad_input_is_refused_with_what_to_do_and_the_scene_untouched(self):
        run = self.godot("test_player.gd", "bad_input", LIPSYNC_TRACKS=self.tracks[0],
                         LIPSYNC_OTHER_MODEL_TRACK=self.other_track, LIPSYNC_NOT_A_TRACK=self.visemes,
                         LIPSYNC_WAV=self.wav, LIPSYNC_NOT_UTF8=self.not_utf8, LIPSYNC_BOM_TRACK=self.bom_track,
                         LIPSYNC_PHONEMES=os.path.join(CLOSURES, "flite_1.psdur"))
        self.assertPassed(run)
        # No flood of Godot's own decoding errors before the add-on's message (a WAV read as text
        # gave one per line), nor the JSON parser's error for a phoneme file; and the mesh's lack of
        # shapes is said only where it lacks them all.
        self.assertNotIn("Unicode error", run.stdout + run.stderr)
        self.assertNotIn("Error parsing JSON", run.stderr)
        self.assertEqual(run.stderr.count("has none of the blend shapes"), 1, run.stderr[-4000:])
        # push_error's messages, as a Godot user sees them.
        for expected in [f"{self.wav}: a WAV file (audio), not a track; give it to the AudioStreamPlayer",
                         f"{self.not_utf8}: not a text file (byte 40 is not UTF-8)",
                         "flite_1.psdur: not a lipsyncd track: not JSON (it begins 'pau:0.",
                         "'lipsync render flite_1.psdur -o flite_1.json'",
                         "has no blend shapes [MouthOpen] that `mapping` names (it has [Key 1, Smile])",
                         "`mapping`['jawOpen'] is 5; give a blend shape name, an array of names, or null",
                         "blend shape 'mouthClose' would be driven by both 'jawOpen' and 'mouthClose'; map one of "
                         "them elsewhere or to null",
                         "a track of model 'other-rig', but this LipsyncPlayer's mapping is for model 'default'; "
                         "render the track with that model",
                         "not a lipsyncd track (no \"format\": \"lipsync-track\"); render one with 'lipsync render",
                         "cannot open the track",
                         "has none of the blend shapes to animate (it has [Key 1, Smile]); give it ARKit-named shape keys",
                         "has no blend shapes [MouthClosed] that `mapping` names",
                         "`mapping` names [jawOpenWide], which the track does not have",
                         "mesh_path '/root/Nowhere' is not a MeshInstance",
                         "play(): no track; call load_track()"]:
            self.assertIn(expected, run.stderr)

    def test_a_partial_mapping_overrides_its_names_and_the_rest_drive_their_own_shapes(self):
        run = self.godot("test_player.gd", "mapping", LIPSYNC_TRACKS=self.tracks[0])
        self.assertPassed(run)
        self.assertNotIn("ERROR", run.stderr, run.stderr[-4000:])

    def test_a_live_session_is_followed_with_the_media_clock_anchor(self):
        with ServerProcess([LIPSYNCD, "--listen", "127.0.0.1:0", "--http-listen", "127.0.0.1:0", "--log-level",
                            "warn"]) as lipsyncd:
            grpc_address = lipsyncd.address
            # Followed at the address lipsyncd prints, as a user copies it.
            viewer = re.match(r"lipsyncd viewer on (http://\S+/view)", lipsyncd.next_line() or "").group(1)
            # Godot first: it waits for the session (asking every 250 ms) as the producer starts.
            # The producer starts after the follower has found no session (>= 1 s later): it waits.
            environment = self.environment("live", LIPSYNC_WS=viewer, LIPSYNC_SESSION="godot-live",
                                           LIPSYNC_EXPECTED=self.tracks[0], LIPSYNC_EXPECT_RETRIES="1")
            godot = subprocess.Popen([GODOT, "--path", self.project, "-s", "res://test_live.gd"], env=environment,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            # A session that never starts, meanwhile: reported after live_wait_ms (1 s).
            missing = self.godot("test_live.gd", "no_session", LIPSYNC_WS=viewer, LIPSYNC_SESSION="nobody",
                                 LIPSYNC_EXPECTED=self.tracks[0])
            self.assertPassed(missing)
            self.assertIn("start the producer (lipsync stream INPUT --session nobody)", missing.stderr)
            producer = subprocess.run([LIPSYNC, "stream", os.path.join(CLOSURES, "flite_1.psdur"), "--server",
                                       grpc_address, "--session", "godot-live", "-o", os.devnull],
                                      capture_output=True, text=True, timeout=60)
            self.assertEqual(producer.returncode, 0, producer.stderr)
            out, err = godot.communicate(timeout=60)
            self.assertPassed(subprocess.CompletedProcess(godot.args, godot.returncode, out, err))

    def test_a_played_voice_is_heard_live_and_unreadable_players_are_refused(self):
        with ServerProcess([LIPSYNCD, "--listen", "127.0.0.1:0", "--http-listen", "127.0.0.1:0", "--log-level",
                            "warn"]) as lipsyncd:
            viewer = re.match(r"lipsyncd viewer on (http://\S+/view)", lipsyncd.next_line() or "").group(1)
            environment = self.environment("listen", LIPSYNC_WS=viewer, LIPSYNC_SESSION="godot-voice",
                                           LIPSYNC_WAV=self.wav, LIPSYNC_TEXT=self.text, LIPSYNC_OFFLINE=self.wav_track,
                                           LIPSYNC_PHONEMES=os.path.join(CLOSURES, "flite_1.psdur"))
            godot = subprocess.Popen([GODOT, "--path", self.project, "-s", "res://test_listen.gd"], env=environment,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            # Meanwhile, on the same lipsyncd: players it cannot hear, and a voice it refuses.
            bad = self.godot("test_listen.gd", "listen_bad_input", LIPSYNC_WS=viewer, LIPSYNC_SESSION="godot-96k",
                             LIPSYNC_OFFLINE=self.wav_track, LIPSYNC_OGG=self.ogg, LIPSYNC_WAV=self.wav, LIPSYNC_NO_SERVER=f"ws://127.0.0.1:{free_port()}")
            self.assertPassed(bad)
            for expected in [
                    "listen(): audio_player_path '' is not an AudioStreamPlayer; point it at the AudioStreamPlayer that "
                    "plays the voice",
                    "listen(): the AudioStreamPlayer 'Silent' has no stream; give it the voice to speak (a WAV, imported "
                    "as an AudioStreamSample)",
                    "listen(): the AudioStreamPlayer 'Music' plays an AudioStreamOGGVorbis, whose samples Godot 3 does "
                    "not give to scripts; import the voice as a WAV",
                    "listen(): the AudioStreamPlayer 'Compressed' plays an IMA-ADPCM WAV, whose samples the add-on does "
                    "not decode; reimport the WAV with Compress Mode 'Disabled'",
                    "listen(): the AudioStreamPlayer 'Empty' has an AudioStreamSample without samples",
                    "listen(): session 'godot-96k': lipsyncd refused the voice: INVALID_ARGUMENT: rate:",
                    "listen(): session 'nobody': no lipsyncd viewer answered at ws://127.0.0.1:"]:
                self.assertIn(expected, bad.stderr)
            self.assertNotIn("NOT_FOUND", bad.stderr)  # the follower of the refused voice did not wait on
            out, err = godot.communicate(timeout=60)
            self.assertPassed(subprocess.CompletedProcess(godot.args, godot.returncode, out, err))
            self.assertNotIn("LipsyncPlayer:", err, err[-4000:])

    def test_a_bad_viewer_address_is_answered_with_the_address_lipsyncd_prints(self):
        run = self.godot("test_live.gd", "bad_address", LIPSYNC_WS="127.0.0.1:8080", LIPSYNC_SESSION="demo",
                         LIPSYNC_EXPECTED=self.tracks[0])
        self.assertPassed(run)
        self.assertIn("follow(): '127.0.0.1:8080' is not the viewer's address; give the http://HOST:PORT/view "
                      "address lipsyncd prints at start ('lipsyncd viewer on http://...'", run.stderr)

    def test_following_without_a_lipsyncd_says_to_start_one(self):
        run = self.godot("test_live.gd", "no_server", LIPSYNC_WS=f"ws://127.0.0.1:{free_port()}",
                         LIPSYNC_SESSION="nobody", LIPSYNC_EXPECTED=self.tracks[0])
        self.assertPassed(run)
        self.assertIn("start lipsyncd with --http-listen HOST:PORT and follow the http://HOST:PORT/view address it "
                      "prints", run.stderr)


if __name__ == "__main__":
    if GODOT is None:
        print("godot3-server is not installed (apt-get install godot3-server): skipped")
        sys.exit(77)
    unittest.main(argv=[sys.argv[0]], verbosity=2)
