#!/usr/bin/python3
"""lipsyncd's audio path and HeadAudio, the browser's live peer, on the same recorded speech.

Harvard sentences (tests/support/harvard_sentences.hpp; 31-50 by default: of the audio path's
rules only the closure refiner's pause after a /p b/ was chosen on 21-50, on espeak-ng's misses
with the transcript, and docs/input-formats.md finds it moves nothing without one) are spoken by Festival (kal_diphone; its segment relation via
utt.save.segs), flite (slt; -psdur) and espeak-ng (en-us at 175 words a minute, the project's
defaults, through libespeak-ng's phoneme events; its stops moved back to the start of the
digital silence of their closure, as tests/speech/tts_recordings.hpp does); each synthesiser's
own phone timings are the truth. The five LibriVox recordings of pocketsphinx-testdata are
added with tests/data/librivox's TextGrids as their truth: those are lipsyncd's own PocketSphinx
forced alignments with the transcript, so on LibriVox the truth and lipsyncd's aligner agree by
construction where they agree at all (read its rows with that in mind).

Each WAV goes, from the audio alone, to:

  HeadAudio   tools/headaudio/run_headaudio.mjs WAV: its Processor in Node, fed 128-sample
              blocks; viseme steps in µs on the WAV's clock (the package is fetched into
              build/headaudio/ by tools/headaudio/fetch_headaudio.sh; nothing is committed)
  lipsyncd    --lipsync-cmd, by default `{lipsync} render {wav} --format visemes-oculus -o {out}`:
              lipsync-visemes JSON, whose frames carry the winning Oculus viseme

and each is scored at the middle of every reference phone of three classes: a bilabial /p b m/
must show the Oculus viseme PP, /f v/ FF, an open vowel /aa ae ah/ aa (the phones both tools
put under aa: lipsyncd's Oculus aa is aa ae ah ay aw, HeadAudio's model trains aa on æ ɑ ʌ;
compare_rhubarb.py's class also has /eh/, which both show as E). What a tool shows at a time is
the viseme holding then: HeadAudio's last step at or before it, lipsyncd's last frame at or
before it (its events change only at frames). The table gives shown / total per source, class
and tool; --misses lists each miss.

The lipsync command is a template so that another path (a live `lipsync listen {wav} ... -o
{out}`) is scored the same way: {lipsync} is --lipsync, {wav} the recording, {out} the file it
must write (lipsync-visemes JSON, or a JSON list of {"t_us", "viseme"} steps as run_headaudio.mjs
prints), {text_file} the transcript (a file; LibriVox's from its TextGrid's words) for a path
that wants one; --lipsync-args are appended. --lipsync-label names its rows.

Run by hand; the ctest listen_is_ahead_of_headaudio_in_every_class
(tests/server/listen_vs_headaudio_test.py) imports its functions for a small held-out set.
Needs /usr/bin/python3, node and npm (or --headaudio-package), and festival, flite,
libespeak-ng1 and pocketsphinx-testdata for their sources (a missing one is skipped with a
note); the default set (65 recordings) with both tools takes about 100 s.
Usage: tools/speech/compare_headaudio.py [--lipsync build/clients/cli/lipsync] [--sentences FROM-TO]
       [--voices festival,flite,espeak] [--no-librivox] [--lipsync-cmd TEMPLATE] [--lipsync-args "ARGS"]
       [--lipsync-label NAME] [--no-headaudio] [--headaudio-node-reading] [--headaudio-advance-ms MS]
       [--headaudio-package DIR] [--misses] [--keep DIR]
"""
import argparse
import array
import collections
import ctypes
import ctypes.util
import glob
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import wave

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
HARVARD_FILE = os.path.join(REPO, "tests", "support", "harvard_sentences.hpp")
ESPEAK_PHONE_SET = os.path.join(REPO, "data", "phonesets", "espeak.json")
LIBRIVOX_TRUTH = os.path.join(REPO, "tests", "data", "librivox")
LIBRIVOX_AUDIO = "/usr/share/pocketsphinx/test/data/librivox"
FETCH_HEADAUDIO = os.path.join(REPO, "tools", "headaudio", "fetch_headaudio.sh")
RUN_HEADAUDIO = os.path.join(REPO, "tools", "headaudio", "run_headaudio.mjs")
DEFAULT_LIPSYNC_CMD = "{lipsync} render {wav} --format visemes-oculus -o {out}"

# Reference phone (ARPAbet, lower case: Festival's and flite's radio set, LibriVox's TextGrids,
# espeak-ng's mnemonics through data/phonesets/espeak.json) -> the Oculus viseme that shows it.
CLASSES = {
    "/p b m/ (PP)": ({"p", "b", "m", "em"}, "PP"),
    "/f v/ (FF)": ({"f", "v"}, "FF"),
    "/aa ae ah/ (aa)": ({"aa", "ae", "ah"}, "aa"),
}


def read_harvard():
    with open(HARVARD_FILE, encoding="utf-8") as harvard_file:
        return re.findall(r'^\s*"(.*)",?$', harvard_file.read(), re.M)


def run(command, **kwargs):
    try:
        result = subprocess.run(command, capture_output=True, text=True, **kwargs)
    except OSError as error:  # not there, not executable
        raise RuntimeError(f"{shlex.join(command)}: {error.strerror}") from error
    if result.returncode != 0:
        raise RuntimeError(f"{shlex.join(command)} failed ({result.returncode}): {result.stderr.strip()[-400:]}")
    return result.stdout


# ---- Sources: a WAV and its reference phones [(label, start_s, end_s)] -------------------------

# Festival's and flite's speech with their own phone timings: compare_rhubarb.py's, the same truth.
from compare_rhubarb import festival, flite  # noqa: E402  (beside this script)


class EspeakEvent(ctypes.Structure):
    """espeak_EVENT (espeak-ng/speak_lib.h)."""
    _fields_ = [("type", ctypes.c_int), ("unique_identifier", ctypes.c_uint), ("text_position", ctypes.c_int),
                ("length", ctypes.c_int), ("audio_position", ctypes.c_int), ("sample", ctypes.c_int),
                ("user_data", ctypes.c_void_p), ("id", ctypes.c_char * 8)]


class Espeak:
    """espeak-ng's library in this process, as core/speech/src/espeak_synthesis.cpp drives it:
    synchronous output, phoneme events with the sample each phoneme starts at; a phoneme ends
    where the next starts, zero-length ones (stress changes) are dropped."""
    AUDIO_OUTPUT_SYNCHRONOUS, EVENT_PHONEME, INITIALIZE_PHONEME_EVENTS, INITIALIZE_DONT_EXIT = 2, 7, 0x0001, 0x8000
    CALLBACK = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.POINTER(EspeakEvent))

    def __init__(self, voice="en-us", words_per_minute=175):
        name = ctypes.util.find_library("espeak-ng") or "libespeak-ng.so.1"
        self.lib = ctypes.CDLL(name)
        self.rate_hz = self.lib.espeak_Initialize(self.AUDIO_OUTPUT_SYNCHRONOUS, 0, None,
                                                  self.INITIALIZE_PHONEME_EVENTS | self.INITIALIZE_DONT_EXIT)
        if self.rate_hz <= 0:
            raise RuntimeError("cannot initialise espeak-ng (is espeak-ng-data installed?)")
        self.callback = self.CALLBACK(self._collect)  # kept alive as long as the library may call it
        self.lib.espeak_SetSynthCallback(self.callback)
        if self.lib.espeak_SetVoiceByName(voice.encode()) != 0:
            raise RuntimeError(f"espeak-ng has no voice {voice}")
        self.lib.espeak_SetParameter(1, words_per_minute, 0)  # espeakRATE
        with open(ESPEAK_PHONE_SET, encoding="utf-8") as f:
            phone_set = json.load(f)
        self.ignored = phone_set.get("ignore_characters", "")
        self.to_arpabet = phone_set["phones"]
        self.samples, self.starts = [], []

    def _collect(self, wav, count, events):
        if wav and count > 0:
            self.samples.extend(wav[:count])
        i = 0
        while events[i].type != 0:  # espeakEVENT_LIST_TERMINATED
            if events[i].type == self.EVENT_PHONEME:
                self.starts.append((events[i].id.decode("utf-8", "replace"), events[i].sample))
            i += 1
        return 0

    def speak(self, text, wav):
        self.samples, self.starts = [], []
        data = text.encode() + b"\0"
        status = self.lib.espeak_Synth(data, ctypes.c_size_t(len(data)), 0, 1, 0, 1, None, None)  # POS_CHARACTER, UTF-8
        self.lib.espeak_Synchronize()
        if status != 0:
            raise RuntimeError(f"espeak-ng synthesis failed ({status})")
        samples = self.samples
        with wave.open(wav, "wb") as out:
            out.setnchannels(1)
            out.setsampwidth(2)
            out.setframerate(self.rate_hz)
            out.writeframes(array.array("h", samples).tobytes())  # native order: little-endian here
        phones = []  # [label, start_sample, end_sample]
        for i, (name, start) in enumerate(self.starts):
            start = min(max(start, phones[-1][1] if phones else 0), len(samples))
            end = min(max(self.starts[i + 1][1], start), len(samples)) if i + 1 < len(self.starts) else len(samples)
            if end > start:
                label = "".join(c for c in name if c not in self.ignored)
                phones.append([self.to_arpabet.get(label, label), start, end])
        stops_from_their_closures(samples, self.rate_hz, phones)
        return [(label, start / self.rate_hz, end / self.rate_hz) for label, start, end in phones]


def stops_from_their_closures(samples, rate_hz, phones):
    """tests/speech/tts_recordings.hpp's espeak_stops_from_their_closures: espeak-ng times a stop at
    its burst and writes its closure as digital silence at the end of the phoneme before; a /p b t
    d k g/ after such a silence (samples of magnitude <= 32, 10 ms or more, ending within 5 ms of
    the label, starting after the previous phoneme does) is moved back to where the silence starts."""
    quiet = lambda k: 0 <= k < len(samples) and abs(samples[k]) <= 32
    for i in range(1, len(phones)):
        stop, previous = phones[i], phones[i - 1]
        if stop[0] not in {"p", "b", "t", "d", "k", "g"}:
            continue
        end = stop[1]
        earliest_end = end - 5 * rate_hz // 1000
        while end > earliest_end and not quiet(end - 1):
            end -= 1
        begin = end
        while begin > 0 and quiet(begin - 1):
            begin -= 1
        if end - begin < 10 * rate_hz // 1000 or begin <= previous[1]:
            continue
        previous[2] = stop[1] = begin


def read_textgrid_tier(path, tier):
    """The intervals [(text, xmin, xmax)] of the interval tier `tier` of a long-format TextGrid."""
    intervals, in_tier, interval = [], False, None
    with open(path, encoding="utf-8") as f:
        for line in f:
            key, _, value = (part.strip() for part in line.partition("="))
            if key == "name":
                in_tier, interval = value.strip('"') == tier, None
            elif in_tier and key.startswith("intervals ["):
                interval = {}
            elif interval is not None and key in ("xmin", "xmax", "text"):
                interval[key] = value.strip('"') if key == "text" else float(value)
                if key == "text":
                    intervals.append((interval["text"], interval["xmin"], interval["xmax"]))
                    interval = None
    return intervals


def librivox_recordings():
    """[(number, wav, words, phones)] for each LibriVox TextGrid whose WAV is installed."""
    recordings = []
    for grid in sorted(glob.glob(os.path.join(LIBRIVOX_TRUTH, "sense_and_sensibility_*.TextGrid"))):
        number = re.search(r"_(\d+)\.TextGrid$", grid).group(1)
        wav = os.path.join(LIBRIVOX_AUDIO, f"sense_and_sensibility_01_austen_64kb-{number}.wav")
        if os.path.exists(wav):
            words = " ".join(text for text, _, _ in read_textgrid_tier(grid, "words") if text)
            phones = [(text.lower(), start, end) for text, start, end in read_textgrid_tier(grid, "phones")]
            recordings.append((number, wav, words, phones))
    return recordings


# ---- Tools: a WAV -> viseme steps [(start_s, oculus_name)] ---------------------------------

def read_viseme_steps(path):
    """A lipsync-visemes JSON (its frames' winners, else its events), or a list of
    {"t_us", "viseme"} steps (run_headaudio.mjs), as [(start_s, name)] in time order."""
    with open(path, encoding="utf-8") as f:
        document = json.load(f)
    if isinstance(document, list):
        return [(step["t_us"] / 1e6, step["viseme"]) for step in document]
    names = document["visemes"]
    frames = document.get("frames") or [{"t_us": e["start_us"], "viseme": e["viseme"]} for e in document["events"]]
    return [(frame["t_us"] / 1e6, names[frame["viseme"]]) for frame in frames]


def viseme_at(steps, t):
    shown = "sil"
    for start, name in steps:
        if start > t:
            break
        shown = name
    return shown


class HeadAudio:
    def __init__(self, package, node_reading, advance_s):
        self.options = ["--package", package] + (["--node-reading"] if node_reading else [])
        self.advance_s = advance_s

    def visemes(self, wav, text_file, out):
        with open(out, "w", encoding="utf-8") as f:
            f.write(run(["node", RUN_HEADAUDIO, wav] + self.options))
        return [(start - self.advance_s, name) for start, name in read_viseme_steps(out)]


class LipsyncCommand:
    def __init__(self, template, lipsync, extra_args):
        self.template, self.lipsync, self.extra_args = shlex.split(template), lipsync, shlex.split(extra_args)

    def visemes(self, wav, text_file, out):
        fields = {"lipsync": self.lipsync or "lipsync", "wav": wav, "out": out, "text_file": text_file}
        run([token.format(**fields) for token in self.template] + self.extra_args)
        return read_viseme_steps(out)


Recording = collections.namedtuple("Recording", "source item wav text_file phones")


def spoken_recordings(speakers, harvard, first, last, work, with_librivox):
    """Each Harvard sentence first..last spoken by each speaker into `work`, then the LibriVox
    recordings, as Recordings (made one at a time, as they are scored)."""
    for source, speak in speakers.items():
        for number in range(first, last + 1):
            stem = os.path.join(work, f"{source}-{number}")
            with open(stem + ".txt", "w", encoding="utf-8") as f:
                f.write(harvard[number - 1] + "\n")
            yield Recording(source, str(number), stem + ".wav", stem + ".txt", speak(harvard[number - 1], stem + ".wav"))
    if not with_librivox:
        return
    found = librivox_recordings()
    if not found:
        print(f"note: LibriVox left out: no WAVs in {LIBRIVOX_AUDIO} (pocketsphinx-testdata)", file=sys.stderr)
    for number, wav, words, phones in found:
        text_file = os.path.join(work, f"LibriVox-{number}.txt")
        with open(text_file, "w", encoding="utf-8") as f:
            f.write(words + "\n")
        yield Recording("LibriVox", number, wav, text_file, phones)


class Tally:
    """shown / total per (source, tool) and class, with "all" over the sources, and what each
    tool showed instead where it missed. `classes`: {name: (reference labels, wanted viseme)}."""

    def __init__(self, classes=CLASSES):
        self.classes = classes
        self.counts = {}  # counts[(source, tool)][class] = [shown, total]
        self.shown_instead = {}  # shown_instead[(tool, class)][viseme] = misses that showed it

    def score(self, tool, recording, steps, print_misses):
        for key in ((recording.source, tool), ("all", tool)):
            self.counts.setdefault(key, {cls: [0, 0] for cls in self.classes})
        for label, start, end in recording.phones:
            for cls, (members, wanted) in self.classes.items():
                if label not in members:
                    continue
                middle = (start + end) / 2
                shown = viseme_at(steps, middle)
                for key in ((recording.source, tool), ("all", tool)):
                    self.counts[key][cls][0] += shown == wanted
                    self.counts[key][cls][1] += 1
                if shown != wanted:
                    instead = self.shown_instead.setdefault((tool, cls), {})
                    instead[shown] = instead.get(shown, 0) + 1
                    if print_misses:
                        print(f"miss: {tool}, {recording.source} {recording.item}: /{label}/ at {middle:.3f} s shows {shown}")

    def cells(self, source, tool):
        """The table's cells of (source, tool): "shown/total (percent)" per class."""
        return [f"{shown}/{total} ({100 * shown / total:.0f} %)" if total else "0/0"
                for shown, total in self.counts[(source, tool)].values()]

    def shown(self, source, tool, cls):
        """(shown, total) of class `cls` for `tool` on `source` ("all": every source)."""
        return tuple(self.counts.get((source, tool), {}).get(cls, (0, 0)))

    def print_table(self, sources, tools):
        print("| source | tool | " + " | ".join(self.classes) + " |")
        print("|---|---|" + "---:|" * len(self.classes))
        for source, tool in sorted(self.counts, key=lambda key: (sources.index(key[0]), tools.index(key[1]))):
            print(f"| {source} | {tool} | " + " | ".join(self.cells(source, tool)) + " |")

    def print_shown_instead(self):
        print("\nShown instead (all sources):")
        for (tool, cls), instead in sorted(self.shown_instead.items()):
            ranked = sorted(instead.items(), key=lambda kv: (-kv[1], kv[0]))
            print(f"  {tool}, {cls}: " + ", ".join(f"{name} {count}" for name, count in ranked))


def fetch_headaudio(cache_dir=None):
    """HeadAudio's unpacked package (fetch_headaudio.sh into cache_dir, by default its own
    build/headaudio/); RuntimeError with npm's message where it cannot be fetched."""
    return run([FETCH_HEADAUDIO] + ([cache_dir] if cache_dir else [])).strip().splitlines()[-1]


def installed_speakers(voices):
    """{source: speak(text, wav) -> reference phones} for each of `voices` (festival, flite,
    espeak) that is installed; one that is not is left out with a note on standard error.
    ValueError names a voice that is none of the three."""
    speakers = {}
    for voice in voices:
        if voice == "festival" and shutil.which("festival"):
            speakers["Festival"] = festival
        elif voice == "flite" and shutil.which("flite"):
            speakers["flite"] = flite
        elif voice == "espeak":
            try:
                speakers["espeak-ng"] = Espeak().speak
            except (OSError, RuntimeError) as error:
                print(f"note: espeak-ng left out: {error}", file=sys.stderr)
        elif voice in ("festival", "flite"):
            print(f"note: {voice} left out: not installed", file=sys.stderr)
        else:
            raise ValueError(f"unknown voice {voice} (festival, flite, espeak)")
    return speakers


def score_recordings(recordings, tools, work, print_misses=False):
    """A Tally of every tool {name: runner with .visemes(wav, text_file, out)} on every
    Recording, each tool's output written into `work`."""
    tally = Tally()
    for recording in recordings:
        for tool, runner in tools.items():
            out = os.path.join(work, f"{recording.source}-{recording.item}-{re.sub(r'[^A-Za-z0-9]+', '_', tool)}.json")
            tally.score(tool, recording, runner.visemes(recording.wav, recording.text_file, out), print_misses)
    return tally


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n".join(__doc__.splitlines()[1:]))
    parser.add_argument("--lipsync", help="the lipsync CLI; without it (or --lipsync-cmd) only HeadAudio is scored")
    parser.add_argument("--lipsync-cmd", help=f"the command that writes {{out}} from {{wav}} (default: {DEFAULT_LIPSYNC_CMD})")
    parser.add_argument("--lipsync-args", default="", help="more arguments appended to the lipsync command (space-separated)")
    parser.add_argument("--lipsync-label", default="lipsyncd", help="the lipsync command's name in the table")
    parser.add_argument("--sentences", default="31-50", help="Harvard sentences FROM-TO (1-based), or N for one (default 31-50)")
    parser.add_argument("--voices", default="festival,flite,espeak", help="synthesisers to speak them (default: all three)")
    parser.add_argument("--no-librivox", action="store_true", help="leave out the LibriVox recordings")
    parser.add_argument("--no-headaudio", action="store_true", help="score the lipsync command alone")
    parser.add_argument("--headaudio-node-reading", action="store_true",
                        help="score HeadAudio as its node shows it (aa messages ignored; run_headaudio.mjs --node-reading)")
    parser.add_argument("--headaudio-advance-ms", type=float, default=0,
                        help="move HeadAudio's steps this much earlier (as a DelayNode on the audio would; default 0)")
    parser.add_argument("--headaudio-package", help="HeadAudio's unpacked package (default: fetch_headaudio.sh's)")
    parser.add_argument("--misses", action="store_true", help="print each miss: tool, source, phone, time, viseme shown")
    parser.add_argument("--keep", metavar="DIR", help="write the WAVs and every tool's output to DIR and keep them")
    args = parser.parse_args()

    harvard = read_harvard()
    match = re.fullmatch(r"(\d+)(?:-(\d+))?", args.sentences)
    first, last = (int(match.group(1)), int(match.group(2) or match.group(1))) if match else (0, 0)
    if not 1 <= first <= last <= len(harvard):
        sys.exit(f"compare_headaudio: --sentences {args.sentences}: want FROM-TO with 1 <= FROM <= TO <= {len(harvard)}")

    tools = {}
    if not args.no_headaudio:
        package = args.headaudio_package or fetch_headaudio()
        name = "HeadAudio (node)" if args.headaudio_node_reading else "HeadAudio"
        if args.headaudio_advance_ms:
            name += f" {-args.headaudio_advance_ms:+g} ms"
        tools[name] = HeadAudio(package, args.headaudio_node_reading, args.headaudio_advance_ms / 1000)
    if args.lipsync or args.lipsync_cmd:
        if args.lipsync and not os.access(args.lipsync, os.X_OK):
            sys.exit(f"compare_headaudio: {args.lipsync}: not an executable file")
        tools[args.lipsync_label] = LipsyncCommand(args.lipsync_cmd or DEFAULT_LIPSYNC_CMD, args.lipsync, args.lipsync_args)
    if not tools:
        sys.exit("compare_headaudio: nothing to score (--no-headaudio without --lipsync or --lipsync-cmd)")

    try:
        speakers = installed_speakers(filter(None, args.voices.split(",")))
    except ValueError as error:
        sys.exit(f"compare_headaudio: --voices: {error}")

    work = args.keep or tempfile.mkdtemp(prefix="compare_headaudio-")
    os.makedirs(work, exist_ok=True)
    try:
        tally = score_recordings(spoken_recordings(speakers, harvard, first, last, work, not args.no_librivox),
                                 tools, work, args.misses)
    finally:
        if not args.keep:
            shutil.rmtree(work)

    print(f"Harvard sentences {args.sentences}; shown / total at the middles of the reference phones\n")
    tally.print_table(list(speakers) + ["LibriVox", "all"], list(tools))
    if args.misses:
        tally.print_shown_instead()


if __name__ == "__main__":
    try:
        main()
    except RuntimeError as error:  # a synthesiser or a tool failed: its command and message
        sys.exit(f"compare_headaudio: {error}")
