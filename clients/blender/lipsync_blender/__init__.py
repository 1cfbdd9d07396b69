"""lipsyncd tracks on a mesh's shape keys, from a file or straight from a running lipsyncd.

Three operators, in File > Import and in the 3D view's sidebar (tab "Lipsync"):

* Import lipsyncd Track: a track file (JSON, Live Link Face CSV, channel CSV) onto the active
  mesh's shape keys, with an optional mapping file and the speech as a sound strip;
* Render Phonemes with lipsyncd: a phoneme file (``flite -psdur`` output or lipsync utterance
  JSON) rendered by lipsyncd over gRPC, keyed the same way;
* Speak with lipsyncd: a text spoken by lipsyncd (espeak-ng), its audio added and its track keyed.

The work is done by track (reading files), mapping (curves to shape keys), keying (the scene
changes, all or nothing) and live (gRPC). Errors are Blender reports that say what to do; the
scene is left as it was. docs/integrations.md is the manual.
"""

bl_info = {
    "name": "lipsyncd Lip Sync",
    "author": "lipsyncd contributors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > lipsyncd Track; View3D > Sidebar > Lipsync",
    "description": "Coarticulated lip-sync tracks from lipsyncd on ARKit shape keys (files or live over gRPC)",
    "doc_url": "https://github.com/lipsyncd/lipsyncd/blob/main/docs/integrations.md",
    "category": "Animation",
}

import os
import tempfile
import zlib

import bpy
from bpy.props import BoolProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import keying, live, mapping, track


def _preferences(context):
    addon = context.preferences.addons.get(__package__)
    return addon.preferences if addon else None


class LipsyncPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    server: StringProperty(name="lipsyncd address", default="127.0.0.1:50051",
                           description="host:port of a running lipsyncd (gRPC)")
    timeout_s: IntProperty(name="Timeout (s)", default=60, min=1, max=3600,
                           description="Deadline of one render or speak call")

    def draw(self, context):
        self.layout.prop(self, "server")
        self.layout.prop(self, "timeout_s")


class _KeyingOptions:
    """Properties every operator shares: where the track goes and how names map."""

    mapping_path: StringProperty(name="Mapping file", subtype="FILE_PATH", default="",
                                 description="JSON mapping from the track's names to this rig's "
                                             "shape keys (empty: ARKit names)")
    start_frame: IntProperty(name="Start frame", default=1,
                             description="Scene frame of the track's time 0 (and of the audio's start)")
    extend_frame_range: BoolProperty(name="Extend frame range", default=True,
                                     description="Make the scene's end frame reach the track's end")

    def invoke_start_frame(self, context):
        if not self.properties.is_property_set("start_frame"):
            self.start_frame = context.scene.frame_current

    def key_track(self, context, the_track, sound_path, action_name):
        """Resolves names, keys the track, reports; {'FINISHED'} or {'CANCELLED'}."""
        obj = context.active_object
        try:
            keying.check_mesh(obj)
            the_mapping = None
            mapping_file = bpy.path.abspath(self.mapping_path) if self.mapping_path else ""
            if mapping_file:
                the_mapping = mapping.read_mapping(mapping_file)
            resolution = mapping.resolve(the_track, keying.shape_key_names(obj), the_mapping,
                                         mapping_file or "mapping")
            if not resolution.pairs:
                names = ", ".join(list(the_track.arkit)[:4] or list(the_track.channels)[:4])
                raise keying.KeyingError(
                    f"The mesh {obj.name!r} has no shape key for any of the track's curves "
                    f"({names}, ...): name its shape keys after ARKit's blendshapes or give a "
                    "mapping file (docs/integrations.md)")
            applied = keying.apply(context.scene, obj, the_track, resolution.pairs, self.start_frame,
                                   action_name, sound_path, self.extend_frame_range)
        except (track.TrackError, mapping.MappingError, keying.KeyingError) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        closures = sum(1 for k in the_track.kinds if k in ("closure_start", "closure_end"))
        kinds_known = any(k is not None for k in the_track.kinds)  # a Live Link Face CSV has none
        self.report({"INFO"}, (
            f"Keyed {len(applied.keyed)} shape keys of {obj.name!r} at {len(applied.frames)} track "
            + (f"frames ({closures} closure key frames)" if kinds_known else "frames") +
            f", frames {applied.frames[0]:.3f} to "
            f"{applied.frames[-1]:.3f}, action {applied.action.name!r}"
            + (f", audio {os.path.basename(sound_path)!r} from frame {self.start_frame}" if sound_path else "")))
        if resolution.unmapped:
            self.report({"WARNING"}, (
                f"{len(resolution.unmapped)} of the track's ARKit weights have no shape key on "
                f"{obj.name!r} and were not keyed: {', '.join(resolution.unmapped)} (add them, map "
                "them in a mapping file, or map them to null)"))
        if applied.replaced_action:
            self.report({"INFO"}, f"The previous action {applied.replaced_action!r} of the shape keys "
                                  "is no longer active; it is kept with a fake user")
        return {"FINISHED"}


class LIPSYNC_OT_import_track(bpy.types.Operator, ImportHelper, _KeyingOptions):
    """Key a lipsyncd track (JSON or ARKit CSV) on the active mesh's shape keys"""

    bl_idname = "lipsync.import_track"
    bl_label = "Import lipsyncd Track"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json;*.csv", options={"HIDDEN"})
    audio_path: StringProperty(name="Audio (WAV)", subtype="FILE_PATH", default="",
                               description="The speech, added as a sound strip at the start frame")
    csv_fps: IntProperty(name="CSV frame rate", default=60, min=1, max=240,
                         description="The --fps a Live Link Face CSV was rendered at (its "
                                     "timecodes count frames of that rate; 60 is Live Link Face's)")

    def invoke(self, context, event):
        self.invoke_start_frame(context)
        return ImportHelper.invoke(self, context, event)

    def execute(self, context):
        try:
            keying.check_mesh(context.active_object)
            the_track = track.read_track(bpy.path.abspath(self.filepath), self.csv_fps)
        except (track.TrackError, keying.KeyingError) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        sound = bpy.path.abspath(self.audio_path) if self.audio_path else None
        name = "Lipsync " + os.path.splitext(os.path.basename(self.filepath))[0]
        return self.key_track(context, the_track, sound, name)


class _LiveOptions(_KeyingOptions):
    fps: IntProperty(name="Track fps", default=0, min=0, max=240,
                     description="Rate of the track's uniform frames (0: lipsyncd's default, 30); "
                                 "closure key frames come on top")
    model: StringProperty(name="Model", default="", description="lipsyncd model (empty: its default)")

    def run_live(self, context, call):
        wm = context.window_manager
        prefs = _preferences(context)
        address = prefs.server if prefs else "127.0.0.1:50051"
        timeout_s = float(prefs.timeout_s) if prefs else 60.0
        try:
            keying.check_mesh(context.active_object)
        except keying.KeyingError as error:
            self.report({"ERROR"}, str(error))
            return None
        wm.progress_begin(0, 1000)
        try:
            return call(address, timeout_s, lambda fraction: wm.progress_update(int(fraction * 1000)))
        except live.LiveError as error:
            self.report({"ERROR"}, str(error))
            return None
        finally:
            wm.progress_end()


class LIPSYNC_OT_render_phonemes(bpy.types.Operator, ImportHelper, _LiveOptions):
    """Render a phoneme file (flite -psdur or lipsync JSON) with lipsyncd and key it on the active mesh"""

    bl_idname = "lipsync.render_phonemes"
    bl_label = "Render Phonemes with lipsyncd"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json;*.psdur;*.txt", options={"HIDDEN"})
    phone_set: StringProperty(name="Phone set", default="",
                              description="Override the file's phone set (flite: radio; JSON: its phone_set)")
    audio_path: StringProperty(name="Audio (WAV)", subtype="FILE_PATH", default="",
                               description="The speech, added as a sound strip at the start frame")

    def invoke(self, context, event):
        self.invoke_start_frame(context)
        return ImportHelper.invoke(self, context, event)

    def execute(self, context):
        path = bpy.path.abspath(self.filepath)

        def call(address, timeout_s, progress):
            phonemes, phone_set = live.read_phonemes(path)
            return live.render_phonemes(address, phonemes, self.phone_set or phone_set, model=self.model,
                                        fps=self.fps, timeout_s=timeout_s, progress=progress)

        the_track = self.run_live(context, call)
        if the_track is None:
            return {"CANCELLED"}
        sound = bpy.path.abspath(self.audio_path) if self.audio_path else None
        name = "Lipsync " + os.path.splitext(os.path.basename(path))[0]
        return self.key_track(context, the_track, sound, name)


class LIPSYNC_OT_speak(bpy.types.Operator, _LiveOptions):
    """Have lipsyncd speak a text (espeak-ng): its audio becomes a sound strip, its track shape-key animation"""

    bl_idname = "lipsync.speak"
    bl_label = "Speak with lipsyncd"
    bl_options = {"REGISTER", "UNDO"}

    text: StringProperty(name="Text", default="Papa bought five more big maps.")
    voice: StringProperty(name="Voice", default="", description="espeak-ng voice (empty: en-us)")
    wav_path: StringProperty(name="Audio file", subtype="FILE_PATH", default="",
                             description="Where the speech is written (empty: next to the .blend "
                                         "file, or the temporary folder for an unsaved one); the "
                                         "sound is packed into the .blend file")

    def invoke(self, context, event):
        self.invoke_start_frame(context)
        return context.window_manager.invoke_props_dialog(self, width=420)

    def _wav_path(self):
        if self.wav_path:
            return bpy.path.abspath(self.wav_path)
        folder = os.path.dirname(bpy.data.filepath) if bpy.data.filepath else tempfile.gettempdir()
        return os.path.join(folder, f"lipsync_speech_{zlib.crc32(self.text.encode()):08x}.wav")

    def execute(self, context):
        if not self.text.strip():
            self.report({"ERROR"}, "Nothing to speak: type a text")
            return {"CANCELLED"}
        wav = self._wav_path()

        def call(address, timeout_s, progress):
            return live.speak(address, self.text, wav, voice=self.voice, model=self.model, fps=self.fps,
                              timeout_s=timeout_s, progress=progress)

        the_track = self.run_live(context, call)
        if the_track is None:
            return {"CANCELLED"}
        result = self.key_track(context, the_track, wav, "Lipsync speech")
        if result == {"FINISHED"}:
            editor = context.scene.sequence_editor
            strips = [s for s in editor.sequences_all if s.type == "SOUND" and
                      bpy.path.abspath(s.sound.filepath) == wav]
            if strips and strips[-1].sound.packed_file is None:
                strips[-1].sound.pack()
        return result


class LIPSYNC_PT_sidebar(bpy.types.Panel):
    bl_label = "lipsyncd"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Lipsync"

    def draw(self, context):
        column = self.layout.column(align=True)
        column.operator(LIPSYNC_OT_import_track.bl_idname, icon="IMPORT")
        column.operator(LIPSYNC_OT_render_phonemes.bl_idname, icon="FILE_SOUND")
        column.operator(LIPSYNC_OT_speak.bl_idname, icon="SPEAKER")
        prefs = _preferences(context)
        if prefs:
            self.layout.prop(prefs, "server")


def _menu_import(self, context):
    self.layout.operator(LIPSYNC_OT_import_track.bl_idname, text="lipsyncd Track (.json, .csv)")


_CLASSES = (LipsyncPreferences, LIPSYNC_OT_import_track, LIPSYNC_OT_render_phonemes, LIPSYNC_OT_speak,
            LIPSYNC_PT_sidebar)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.TOPBAR_MT_file_import.append(_menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(_menu_import)
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
