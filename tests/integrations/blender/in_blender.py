"""The add-on's checks inside Blender (headless), run by blender_test.py.

blender -b --factory-startup --python-exit-code 1 --python in_blender.py -- CONFIG.json

CONFIG names the group of checks ("import", "demo", "gltf" or "live") and the files the harness made
from real speech (flite's timings and WAV, tracks rendered by the built `lipsync`). The add-on
is installed from the zip the build makes, as a user does (Preferences > Add-ons > Install),
into the throw-away user folder the harness points BLENDER_USER_SCRIPTS at. Every check runs
its operator through bpy.ops, as the UI does: errors arrive as RuntimeError carrying the
operator's report. A failing check makes Blender exit 1.
"""

import importlib.util
import json
import os
import re
import shlex
import struct
import subprocess
import sys
import tempfile
import time
import unittest

import bpy


def _load_demo_face():
    """clients/blender/demo_face.py, by its path: that folder on sys.path would hide the add-on
    installed from the zip behind its sources."""
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "clients", "blender",
                        "demo_face.py")
    spec = importlib.util.spec_from_file_location("demo_face", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


demo_face = _load_demo_face()

CONFIG = json.load(open(sys.argv[sys.argv.index("--") + 1], encoding="utf-8"))
CLOSURE_KINDS = ("closure_start", "closure_end")


def f32(value):
    return struct.unpack("<f", struct.pack("<f", value))[0]


def install_addon():
    """As Edit > Preferences > Add-ons > Install, then the tick box."""
    bpy.ops.preferences.addon_install(filepath=CONFIG["addon_zip"], overwrite=True)
    bpy.ops.preferences.addon_enable(module="lipsync_blender")
    for operator in ("import_track", "render_phonemes", "speak"):
        assert hasattr(bpy.ops.lipsync, operator), f"the add-on did not register lipsync.{operator}"
    assert hasattr(bpy.types, "LIPSYNC_PT_sidebar"), "the add-on's sidebar panel is not registered"
    menu = [f.__name__ for f in bpy.types.TOPBAR_MT_file_import._dyn_ui_initialize()]
    assert "_menu_import" in menu, f"File > Import has no lipsyncd entry: {menu}"


def load_json(path):
    with open(path, encoding="utf-8") as stream:
        return json.load(stream)


def reset_scene(fps=24):
    """An empty scene (the add-on stays installed)."""
    scene = bpy.context.scene
    for data in (bpy.data.objects, bpy.data.meshes, bpy.data.actions, bpy.data.sounds):
        for item in list(data):
            data.remove(item)
    scene.sequence_editor_clear()
    scene.render.fps, scene.render.fps_base = fps, 1.0
    scene.frame_start, scene.frame_end = 1, 10
    return scene


def snapshot(scene):
    """What an operator must leave unchanged when it fails."""
    keys = {}
    for obj in scene.objects:
        key = obj.data.shape_keys if obj.type == "MESH" else None
        if key is not None:
            ad = key.animation_data
            keys[obj.name] = (ad.action.name if ad and ad.action else None,
                              [kb.value for kb in key.key_blocks])
    strips = [(s.name, s.frame_start) for s in scene.sequence_editor.sequences_all] \
        if scene.sequence_editor else None
    return {"actions": sorted(a.name for a in bpy.data.actions),
            "fcurves": sorted((a.name, len(a.fcurves)) for a in bpy.data.actions),
            "sounds": sorted(s.name for s in bpy.data.sounds),
            "strips": strips, "frame_end": scene.frame_end, "keys": keys}


def capture_stdout(call):
    """Runs call() with file descriptor 1 going to a file: Blender prints reports there."""
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile(mode="w+b") as sink:
        os.dup2(sink.fileno(), 1)
        try:
            result = call()
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)
        sink.seek(0)
        return result, sink.read().decode("utf-8", "replace")


class KeyedTrackChecks(unittest.TestCase):
    """Shared assertions: the F-curves hold every frame of the track, at its exact time."""

    def fcurves_by_key(self, obj):
        action = obj.data.shape_keys.animation_data.action
        self.assertIsNotNone(action, "the track's action is not the Key's active action")
        curves = {}
        for fc in action.fcurves:
            name = fc.data_path[len('key_blocks["'):-len('"].value')]
            curves[name] = fc
        return curves

    def assert_keys_equal_track(self, obj, track, start_frame, fps, names=None, mapping=None):
        """Every named shape key: one key per track frame, at the frame of its time, with its value."""
        names = names or track["arkit_names"]
        arkit = {n: i for i, n in enumerate(track["arkit_names"])}
        channels = {n: i for i, n in enumerate(track["channels"])}
        curves = self.fcurves_by_key(obj)
        frames = track["frames"]
        for name in names:
            source = (mapping or {}).get(name, name)
            fc = curves.get(name)
            self.assertIsNotNone(fc, f"no F-curve for shape key {name!r}")
            points = fc.keyframe_points
            self.assertEqual(len(points), len(frames), f"{name}: keys vs track frames")
            co = [0.0] * (2 * len(points))
            points.foreach_get("co", co)
            want_frames = [f32(start_frame + f["t_us"] * fps / 1e6) for f in frames]
            if source in arkit:
                want_values = [f32(f["arkit"][arkit[source]]) for f in frames]
            else:
                want_values = [f32(f["values"][channels[source]]) for f in frames]
            self.assertEqual(co[0::2], want_frames, f"{name}: key frames differ from the track's times")
            self.assertEqual(co[1::2], want_values, f"{name}: key values differ from the track's")
            self.assertTrue(all(p.interpolation == "LINEAR" for p in points), f"{name}: not LINEAR")

    def assert_closures_hold(self, obj, track, start_frame, fps):
        """At each closure key frame the F-curves evaluate to the track's values, and the scene at
        that (sub-)frame shows them on the shape keys."""
        scene = bpy.context.scene
        curves = self.fcurves_by_key(obj)
        index = {n: i for i, n in enumerate(track["arkit_names"])}
        closures = [f for f in track["frames"] if f["kind"] in CLOSURE_KINDS]
        self.assertGreaterEqual(len(closures), 6, "real speech with /p b m f v/ has closure key frames")
        fractional = 0
        for frame in closures:
            at = start_frame + frame["t_us"] * fps / 1e6
            fractional += at != int(at)
            want = {n: f32(frame["arkit"][index[n]]) for n in ("jawOpen", "mouthClose", "mouthFunnel",
                                                              "mouthPucker", "mouthRollLower")}
            got = {n: curves[n].evaluate(f32(at)) for n in want}
            for n in want:
                self.assertAlmostEqual(got[n], want[n], delta=1e-6,
                                       msg=f"{n} at the {frame['kind']} key frame {at:.4f} ({frame['t_us']} µs)")
            whole = int(at // 1)
            scene.frame_set(whole, subframe=at - whole)
            blocks = obj.data.shape_keys.key_blocks
            for n in want:
                self.assertAlmostEqual(blocks[n].value, want[n], delta=2e-4,
                                       msg=f"shape key {n} in the scene at frame {at:.4f}")
        self.assertGreater(fractional, 0, "some closure key frames fall between the scene's frames")


class ImportChecks(KeyedTrackChecks):
    def setUp(self):
        self.scene = reset_scene(fps=24)
        self.track = load_json(CONFIG["track_json"])
        self.face = demo_face.build_face(CONFIG["face_json"], self.track["arkit_names"])

    def test_json_track_keys_every_frame_at_its_time_with_the_audio_at_its_start(self):
        result, output = capture_stdout(lambda: bpy.ops.lipsync.import_track(
            filepath=CONFIG["track_json"], audio_path=CONFIG["wav"], start_frame=1))
        self.assertEqual(result, {"FINISHED"}, output)
        self.assertIn("Keyed 52 shape keys of 'Face'", output)
        self.assert_keys_equal_track(self.face, self.track, 1, 24)
        self.assert_closures_hold(self.face, self.track, 1, 24)
        strips = list(self.scene.sequence_editor.sequences_all)
        self.assertEqual(len(strips), 1)
        self.assertEqual((strips[0].type, strips[0].frame_start), ("SOUND", 1))
        self.assertEqual(bpy.path.abspath(strips[0].sound.filepath), CONFIG["wav"])
        self.assertEqual(strips[0].frame_final_duration, round(CONFIG["wav_seconds"] * 24))
        last = 1 + self.track["frames"][-1]["t_us"] * 24 / 1e6
        self.assertEqual(self.scene.frame_end, int(-(-last // 1)), "frame range reaches the track's end")

    def test_festival_track_at_30_fps_on_a_25_fps_scene_from_frame_100(self):
        track = load_json(CONFIG["festival_json"])
        self.scene.render.fps = 25
        self.assertEqual(bpy.ops.lipsync.import_track(filepath=CONFIG["festival_json"], start_frame=100),
                         {"FINISHED"})
        self.assert_keys_equal_track(self.face, track, 100, 25)
        self.assert_closures_hold(self.face, track, 100, 25)

    def test_live_link_face_csv_gives_the_json_tracks_values_at_its_times(self):
        self.assertEqual(bpy.ops.lipsync.import_track(filepath=CONFIG["track_csv60"], csv_fps=60,
                                                      start_frame=1), {"FINISHED"})
        track = load_json(CONFIG["track_json60"])
        curves = self.fcurves_by_key(self.face)
        index = {n: i for i, n in enumerate(track["arkit_names"])}
        self.assertEqual(sorted(curves), sorted(track["arkit_names"]))
        frame_tolerance = 24 / 60 / 2000 + 1e-5  # the timecode keeps 1/1000 of a 60 fps frame
        for name, fc in curves.items():
            points = fc.keyframe_points
            self.assertEqual(len(points), len(track["frames"]), name)
            for point, frame in zip(points, track["frames"]):
                self.assertAlmostEqual(point.co[0], 1 + frame["t_us"] * 24 / 1e6, delta=frame_tolerance)
                self.assertEqual(point.co[1], f32(frame["arkit"][index[name]]), name)

    def test_mapping_file_drives_a_rigs_own_names_and_reports_the_rest(self):
        rig = bpy.data.objects.new("Rig", bpy.data.meshes.new("Rig"))
        rig.data.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [(0, 1, 2)])
        self.scene.collection.objects.link(rig)
        rig.shape_key_add(name="Basis")
        for name in ("Jaw_Open", "Lips_Closed", "JawDrop", "MOUTHFUNNEL"):
            rig.shape_key_add(name=name)
        bpy.context.view_layer.objects.active = rig
        mapping_path = os.path.join(CONFIG["work"], "rig_mapping.json")
        with open(mapping_path, "w", encoding="utf-8") as out:
            json.dump({"shape_keys": {"jawOpen": "Jaw_Open", "mouthClose": "Lips_Closed",
                                      "jaw_rotation": "JawDrop", "eyeBlinkLeft": None}}, out)
        result, output = capture_stdout(lambda: bpy.ops.lipsync.import_track(
            filepath=CONFIG["track_json"], mapping_path=mapping_path, start_frame=1))
        self.assertEqual(result, {"FINISHED"}, output)
        mapping = {"Jaw_Open": "jawOpen", "Lips_Closed": "mouthClose", "JawDrop": "jaw_rotation",
                   "MOUTHFUNNEL": "mouthFunnel"}
        self.assert_keys_equal_track(rig, self.track, 1, 24, names=list(mapping), mapping=mapping)
        self.assertIn("Warning: 48 of the track's ARKit weights have no shape key on 'Rig'", output)
        self.assertIn("mouthPucker", output)
        self.assertNotIn("eyeBlinkLeft,", output, "a name mapped to null is not reported")


class MappingRuleChecks(KeyedTrackChecks):
    """One rule for names, the Godot add-on's too (docs/integrations.md, "Mapping file")."""

    def setUp(self):
        self.scene = reset_scene(fps=24)
        self.track = load_json(CONFIG["track_json"])

    def test_a_partial_mapping_overrides_the_names_it_lists_and_the_rest_drive_their_own_shape_keys(self):
        face = demo_face.build_face(CONFIG["face_json"], self.track["arkit_names"] + ["JawDrop", "CheekRaise_L"])
        mapping_path = os.path.join(CONFIG["work"], "partial_mapping.json")
        with open(mapping_path, "w", encoding="utf-8") as out:
            json.dump({"shape_keys": {"jawOpen": "JawDrop", "mouthSmileLeft": ["mouthSmileLeft", "CheekRaise_L"],
                                      "eyeBlinkLeft": None}}, out)
        result, output = capture_stdout(lambda: bpy.ops.lipsync.import_track(
            filepath=CONFIG["track_json"], mapping_path=mapping_path, start_frame=1))
        self.assertEqual(result, {"FINISHED"}, output)
        driven = {"JawDrop": "jawOpen", "CheekRaise_L": "mouthSmileLeft"}
        driven.update({n: n for n in self.track["arkit_names"] if n not in ("jawOpen", "eyeBlinkLeft")})
        self.assertEqual(sorted(self.fcurves_by_key(face)), sorted(driven),
                         "the shape keys keyed: the mapping's for the names it lists, the ARKit-named for the rest")
        self.assert_keys_equal_track(face, self.track, 1, 24, names=list(driven), mapping=driven)
        self.assertNotIn("Warning", output, "every ARKit weight is keyed or mapped to null")

    def test_a_mapping_that_drives_one_shape_key_from_two_names_is_refused(self):
        demo_face.build_face(CONFIG["face_json"], self.track["arkit_names"])
        mapping_path = os.path.join(CONFIG["work"], "crossed_mapping.json")
        with open(mapping_path, "w", encoding="utf-8") as out:
            json.dump({"shape_keys": {"jawOpen": "mouthClose"}}, out)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.lipsync.import_track(filepath=CONFIG["track_json"], mapping_path=mapping_path)
        self.assertIn("shape key 'mouthClose' would be driven by both 'jawOpen' and 'mouthClose': map one of them "
                      "elsewhere or to null", str(raised.exception))

    def test_a_mapping_to_a_shape_key_the_mesh_lacks_names_that_shape_key(self):
        demo_face.build_face(CONFIG["face_json"], self.track["arkit_names"])
        mapping_path = os.path.join(CONFIG["work"], "missing_mapping.json")
        with open(mapping_path, "w", encoding="utf-8") as out:
            json.dump({"shape_keys": {"jawOpen": "MouthOpen"}}, out)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.lipsync.import_track(filepath=CONFIG["track_json"], mapping_path=mapping_path)
        self.assertIn("'jawOpen' maps to shape key 'MouthOpen', which the mesh does not have",
                      str(raised.exception))


class BadInputChecks(unittest.TestCase):
    """Each bad input: an ERROR report saying what to do, and the scene as it was."""

    def setUp(self):
        self.scene = reset_scene(fps=24)
        self.track = load_json(CONFIG["track_json"])
        self.face = demo_face.build_face(CONFIG["face_json"], self.track["arkit_names"])
        # A previous animation that must survive every failure.
        self.face.data.shape_keys.animation_data_create()
        previous = bpy.data.actions.new("Hand keyed")
        previous.fcurves.new('key_blocks["jawOpen"].value').keyframe_points.insert(1, 0.5)
        self.face.data.shape_keys.animation_data.action = previous
        self.scene.frame_set(1)

    def assert_refused(self, message, **operator_args):
        before = snapshot(self.scene)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.lipsync.import_track(**operator_args)
        self.assertIn(message, str(raised.exception))
        self.assertEqual(snapshot(self.scene), before, "the failed import changed the scene")
        return str(raised.exception)

    def test_a_phoneme_file_of_every_format_lipsync_reads_is_named_as_such(self):
        described = {"flite": "`flite -psdur` output", "json": "lipsync utterance JSON",
                     "textgrid": "a Praat TextGrid", "textgrid_utf16": "a Praat TextGrid",
                     "timit": "a TIMIT .PHN file", "lab": "a Festival .lab file", "pho": "an MBROLA .pho file"}
        self.assertEqual(sorted(CONFIG["phoneme_files"]), sorted(described))
        for kind, path in CONFIG["phoneme_files"].items():
            with self.subTest(kind=kind):
                text = self.assert_refused(f"{path}: not a lipsyncd track but a phoneme file ({described[kind]}: "
                                           "lipsyncd's input, not its output): render it (`lipsync render "
                                           f"{os.path.basename(path)} -o ", filepath=path)
                live = kind in ("flite", "json")
                self.assertEqual("or use Render Phonemes with lipsyncd" in text, live, text)

    def test_the_render_command_a_flite_file_is_answered_with_gives_a_track_that_imports(self):
        text = self.assert_refused("not a lipsyncd track but a phoneme file", filepath=CONFIG["psdur"])
        command = re.search(r"\(`(lipsync render [^`]*)`\) and import (\S+),", text)
        self.assertIsNotNone(command, text)
        self.assertEqual(command.groups(), ("lipsync render papa.psdur -o papa.json", "papa.json"))
        folder = os.path.dirname(CONFIG["psdur"])
        subprocess.run([CONFIG["lipsync"], *shlex.split(command.group(1))[1:]], cwd=folder, check=True,
                       capture_output=True)
        result, output = capture_stdout(lambda: bpy.ops.lipsync.import_track(
            filepath=os.path.join(folder, command.group(2))))
        self.assertEqual(result, {"FINISHED"}, output)
        self.assertIn("Keyed 52 shape keys of 'Face'", output)

    def test_a_wav_given_as_the_track_is_named_as_such(self):
        self.assert_refused(f"{CONFIG['wav']}: not a lipsyncd track but a WAV file (audio): give it as the "
                            "Audio (WAV)", filepath=CONFIG["wav"])

    def test_rhubarb_cues_are_named_as_such(self):
        self.assert_refused("Rhubarb mouth cues", filepath=CONFIG["rhubarb_json"])

    def test_a_channel_csv_without_a_mapping_names_the_way_out(self):
        self.assert_refused("give a mapping file", filepath=CONFIG["channels_csv"])

    def test_a_mapping_for_another_model_names_the_missing_channel(self):
        mapping_path = os.path.join(CONFIG["work"], "default_model_mapping.json")
        with open(mapping_path, "w", encoding="utf-8") as out:
            json.dump({"shape_keys": {"jaw_rotation": "jawOpen", "jawOpen": None}}, out)
        text = self.assert_refused("'jaw_rotation' is not a curve of the track",
                                   filepath=CONFIG["other_model_json"], mapping_path=mapping_path)
        self.assertIn("renamed-jaw", text)

    def test_a_mesh_without_shape_keys(self):
        bpy.ops.mesh.primitive_cube_add()
        self.assert_refused("has no shape keys", filepath=CONFIG["track_json"])

    def test_a_mesh_without_the_tracks_shape_keys(self):
        bpy.ops.mesh.primitive_cube_add()
        cube = bpy.context.active_object
        cube.shape_key_add(name="Basis")
        cube.shape_key_add(name="Smile")
        self.assert_refused("has no shape key for any of the track's curves", filepath=CONFIG["track_json"])

    def test_a_csv_read_at_too_low_a_frame_rate(self):
        self.assert_refused("has frame 30 in a second of 30 frames: set the CSV frame rate to the rate "
                            "the track was rendered at", filepath=CONFIG["track_csv60"], csv_fps=30)

    def test_a_csv_read_at_too_high_a_frame_rate(self):
        self.assert_refused("so the track is at about 60 frames/s, not 120", filepath=CONFIG["track_csv60"],
                            csv_fps=120)

    def test_a_missing_audio_file(self):
        self.assert_refused("does not exist", filepath=CONFIG["track_json"],
                            audio_path=os.path.join(CONFIG["work"], "no such.wav"))

    def test_a_failure_after_the_first_change_is_undone(self):
        addon = sys.modules["lipsync_blender.keying"]
        original = addon._free_channel

        def fail(editor):
            raise addon.KeyingError("planted failure while adding the sound strip")

        addon._free_channel = fail
        try:
            self.assert_refused("planted failure", filepath=CONFIG["track_json"], audio_path=CONFIG["wav"])
        finally:
            addon._free_channel = original
        self.assertEqual(self.face.data.shape_keys.animation_data.action.name, "Hand keyed")


class GltfExport(unittest.TestCase):
    """Keys the track and exports a GLB, as docs/integrations.md says; blender_test.py reads it back."""

    def export(self, glb, **import_options):
        reset_scene(fps=24)
        track = load_json(CONFIG["track_json"])
        demo_face.build_face(CONFIG["face_json"], track["arkit_names"])
        self.assertEqual(bpy.ops.lipsync.import_track(filepath=CONFIG["track_json"], **import_options),
                         {"FINISHED"})
        bpy.ops.export_scene.gltf(filepath=glb, export_format="GLB", export_animations=True,
                                  export_morph=True, export_force_sampling=False, export_apply=False)
        self.assertTrue(os.path.getsize(glb) > 0)

    def test_export_keyed_from_frame_0(self):
        self.export(CONFIG["glb"], start_frame=0)

    def test_export_keyed_from_the_default_start_frame_1(self):
        self.export(CONFIG["glb_frame1"])


class LiveChecks(KeyedTrackChecks):
    def setUp(self):
        self.scene = reset_scene(fps=24)
        self.track = load_json(CONFIG["track_json"])
        self.face = demo_face.build_face(CONFIG["face_json"], self.track["arkit_names"])
        prefs = bpy.context.preferences.addons["lipsync_blender"].preferences
        prefs.server, prefs.timeout_s = CONFIG["server"], 60

    def test_render_from_lipsyncd_equals_the_command_lines_render(self):
        result, output = capture_stdout(lambda: bpy.ops.lipsync.render_phonemes(
            filepath=CONFIG["psdur"], audio_path=CONFIG["wav"], start_frame=1))
        self.assertEqual(result, {"FINISHED"}, output)
        self.assert_keys_equal_track(self.face, self.track, 1, 24)
        self.assert_closures_hold(self.face, self.track, 1, 24)
        self.assertEqual(len(self.scene.sequence_editor.sequences_all), 1)

    def test_render_reports_progress_as_the_frames_arrive(self):
        live = sys.modules["lipsync_blender.live"]
        phonemes, phone_set = live.read_phonemes(CONFIG["psdur"])
        fractions = []
        track = live.render_phonemes(CONFIG["server"], phonemes, phone_set, progress=fractions.append)
        self.assertEqual(len(fractions), len(self.track["frames"]), "one update per frame received")
        self.assertEqual(fractions, sorted(fractions), "progress never goes back")
        self.assertGreater(fractions[0], -1e-9)
        self.assertAlmostEqual(fractions[-1], 1.0, delta=0.05)
        self.assertEqual(track.times_us, [f["t_us"] for f in self.track["frames"]])

    def test_speak_adds_the_speech_and_its_track(self):
        wav = os.path.join(CONFIG["work"], "spoken.wav")
        result, output = capture_stdout(lambda: bpy.ops.lipsync.speak(
            text="Papa bought five more big maps.", wav_path=wav, start_frame=10))
        self.assertEqual(result, {"FINISHED"}, output)
        import wave
        with wave.open(wav, "rb") as stream:
            seconds = stream.getnframes() / stream.getframerate()
        self.assertGreater(seconds, 1.0)
        strip = list(self.scene.sequence_editor.sequences_all)[0]
        self.assertEqual((strip.type, strip.frame_start), ("SOUND", 10))
        self.assertIsNotNone(strip.sound.packed_file, "the speech is packed into the .blend")
        curves = self.fcurves_by_key(self.face)
        jaw = curves["jawOpen"].keyframe_points
        self.assertGreater(len(jaw), seconds * 30 * 0.9)
        self.assertAlmostEqual(jaw[0].co[0], 10.0)
        self.assertLessEqual(jaw[len(jaw) - 1].co[0], 10 + seconds * 24 + 1)
        self.assertIn("closure key frames", output)
        closures = int(output.split(" closure key frames")[0].rsplit("(", 1)[1])
        self.assertGreaterEqual(closures, 6, "/p b m f v/ in the text give closure key frames")

    def test_the_preferences_a_script_sets_as_documented_choose_the_server_and_the_deadline(self):
        with open(os.path.join(CONFIG["source_dir"], "docs/integrations.md"), encoding="utf-8") as stream:
            snippet = re.search(r'```python\n(prefs = bpy\.context\.preferences\.addons\["lipsync_blender"\]'
                                r'\.preferences\n.*?)```', stream.read(), re.S)
        self.assertIsNotNone(snippet, "docs/integrations.md shows no preferences snippet")
        exec(snippet.group(1), {"bpy": bpy})
        prefs = bpy.context.preferences.addons["lipsync_blender"].preferences
        self.assertEqual((prefs.server, prefs.timeout_s), ("render-host:50051", 120))
        # timeout_s bounds the wait for a server that does not answer (5 s at most without it).
        prefs.server, prefs.timeout_s = CONFIG["dead_server"], 1
        started = time.monotonic()
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.lipsync.render_phonemes(filepath=CONFIG["psdur"])
        waited = time.monotonic() - started
        self.assertIn(f"No lipsyncd answers at {CONFIG['dead_server']}", str(raised.exception))
        self.assertLess(waited, 3.0, "the deadline in the preferences was not used")
        prefs.server = CONFIG["server"]
        self.assertEqual(bpy.ops.lipsync.render_phonemes(filepath=CONFIG["psdur"]), {"FINISHED"})
        self.assert_keys_equal_track(self.face, self.track, 1, 24)

    def test_no_lipsyncd_is_an_error_that_leaves_the_scene(self):
        prefs = bpy.context.preferences.addons["lipsync_blender"].preferences
        prefs.server, prefs.timeout_s = CONFIG["dead_server"], 2
        before = snapshot(self.scene)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.lipsync.render_phonemes(filepath=CONFIG["psdur"])
        self.assertIn(f"No lipsyncd answers at {CONFIG['dead_server']}: start it", str(raised.exception))
        self.assertEqual(snapshot(self.scene), before)

    def test_without_grpc_the_report_says_what_to_install(self):
        saved = sys.modules.get("grpc")
        sys.modules["grpc"] = None  # what `import grpc` meets in a Blender without grpcio
        before = snapshot(self.scene)
        try:
            with self.assertRaises(RuntimeError) as raised:
                bpy.ops.lipsync.render_phonemes(filepath=CONFIG["psdur"])
        finally:
            if saved is None:
                del sys.modules["grpc"]
            else:
                sys.modules["grpc"] = saved
        self.assertIn("grpc is not available in Blender's Python", str(raised.exception))
        self.assertIn("apt-get install python3-grpcio python3-protobuf", str(raised.exception))
        self.assertEqual(snapshot(self.scene), before)

    def test_a_refused_phoneme_is_reported_with_the_servers_words(self):
        bad = os.path.join(CONFIG["work"], "bad.psdur")
        with open(bad, "w", encoding="utf-8") as out:
            out.write("pau:0.1 p:0.2 qqq:0.3 pau:0.4\n")
        before = snapshot(self.scene)
        with self.assertRaises(RuntimeError) as raised:
            bpy.ops.lipsync.render_phonemes(filepath=bad)
        self.assertIn("INVALID_ARGUMENT", str(raised.exception))
        self.assertIn("qqq", str(raised.exception))
        self.assertEqual(snapshot(self.scene), before)


class DemoFaceChecks(KeyedTrackChecks):
    """The demo face's .blend (clients/blender/demo_face.py), opened as docs/integrations.md says."""

    def test_the_demo_face_blend_opens_ready_to_import_a_track_with_its_audio(self):
        self.assertEqual(os.path.realpath(bpy.data.filepath), os.path.realpath(CONFIG["demo_blend"]))
        face = bpy.context.active_object
        self.assertIsNotNone(face, "the demo face's .blend opens with no active object")
        self.assertEqual((face.name, face.type, face.select_get()), ("Face", "MESH", True))
        track = load_json(CONFIG["track_json"])
        names = [kb.name for kb in face.data.shape_keys.key_blocks]
        self.assertEqual(names, ["Basis"] + track["arkit_names"])
        moving = [kb.name for kb in face.data.shape_keys.key_blocks[1:]
                  if any(a.co != b.co for a, b in zip(kb.data, face.data.shape_keys.reference_key.data))]
        self.assertIn("jawOpen", moving)
        self.assertIn("mouthClose", moving)
        scene = bpy.context.scene
        self.assertEqual(scene.camera.name, "Camera")
        result, output = capture_stdout(lambda: bpy.ops.lipsync.import_track(
            filepath=CONFIG["track_json"], audio_path=CONFIG["wav"]))
        self.assertEqual(result, {"FINISHED"}, output)
        self.assertIn("Keyed 52 shape keys of 'Face'", output)
        self.assert_keys_equal_track(face, track, 1, scene.render.fps)
        self.assertEqual([(s.type, s.frame_start) for s in scene.sequence_editor.sequences_all], [("SOUND", 1)])


GROUPS = {"import": [ImportChecks, MappingRuleChecks, BadInputChecks], "demo": [DemoFaceChecks], "gltf": [GltfExport],
          "live": [LiveChecks]}

if __name__ == "__main__":
    install_addon()
    suite = unittest.TestSuite(unittest.defaultTestLoader.loadTestsFromTestCase(case)
                               for case in GROUPS[CONFIG["group"]])
    outcome = unittest.TextTestRunner(stream=sys.stderr, verbosity=2).run(suite)
    sys.exit(0 if outcome.wasSuccessful() else 1)
