#!/usr/bin/env python3
"""lipsyncd and Rhubarb Lip Sync side by side on the same recorded speech.

Festival (kal_diphone) and flite (slt) speak the first ten Harvard sentences;
each writes its own phone timings, which are the truth. Both tools turn each WAV
into Rhubarb's mouth shapes (A-H, X; TSV), once from the audio alone and once
with the transcript:

    lipsync render speech.wav [--text-file words.txt] --format rhubarb-tsv --extended-shapes GHX
    rhubarb -f tsv [-d words.txt] speech.wav

and each is scored at the middle of every reference phone of three classes:
a bilabial closure /p b m/ must show shape A (closed), /f v/ shape G (lower lip
under the teeth), a full open vowel /aa ae ah eh/ shape C or D (open). The share
of those middles each tool gets right is printed per class, speaker and mode,
and the wall time of both on a 7.1 s LibriVox recording (pocketsphinx-testdata)
with its transcript, best of three runs.

Outside the build and CI; docs/input-formats.md quotes its output.
Usage: tools/speech/compare_rhubarb.py --lipsync build/clients/cli/lipsync --rhubarb PATH [--sentences N]
       [--misses] [--no-timing] [--lipsync-only] [--lipsync-args "ARGS"]
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

# The first ten Harvard sentences, from the list the speech tests speak (one list for both).
HARVARD_FILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "support",
                            "harvard_sentences.hpp")
with open(HARVARD_FILE, encoding="utf-8") as harvard_file:
    HARVARD = re.findall(r'^\s*"(.*)",$', harvard_file.read(), re.M)[:10]
CLASSES = {  # reference phone (Festival's radio set) -> the shapes that show it
    "closure (A)": ({"p", "b", "m", "em"}, {"A"}),
    "/f v/ (G)": ({"f", "v"}, {"G"}),
    "open vowel (C, D)": ({"aa", "ae", "ah", "eh"}, {"C", "D"}),
}
LIBRIVOX = "/usr/share/pocketsphinx/test/data/librivox/sense_and_sensibility_01_austen_64kb-0870.wav"
LIBRIVOX_TEXT = ("and mister john dashwood had then leisure to consider how much there might be "
                 "prudently in his power to do for them")


def run(command, **kwargs):
    result = subprocess.run(command, capture_output=True, text=True, **kwargs)
    if result.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed ({result.returncode}): {result.stderr.strip()[-400:]}")
    return result.stdout


def festival(text, wav):
    out = run(["festival", "-b", "(voice_kal_diphone)", f'(set! u (SynthText "{text}"))',
               f'(utt.save.wave u "{wav}")', '(utt.save.segs u "-")'])
    phones, start = [], 0.0
    past_header = False
    for line in out.splitlines():
        if line.strip() == "#":
            past_header = True
            continue
        fields = line.split()
        if past_header and len(fields) == 3:
            end = float(fields[0])
            phones.append((fields[2], start, end))
            start = end
    return phones


def flite(text, wav):
    out = run(["flite", "-voice", "slt", "-psdur", "-t", text, "-o", wav])
    phones, start = [], 0.0
    for pair in out.split():
        name, end = pair.rsplit(":", 1)
        phones.append((name, start, float(end)))
        start = float(end)
    return phones


def read_tsv(path):
    shapes = []
    with open(path) as f:
        for line in f:
            fields = line.split()
            if len(fields) >= 2:
                shapes.append((float(fields[0]), fields[1]))
    return shapes


def shape_at(shapes, t):
    current = "X"
    for start, shape in shapes:
        if start > t:
            break
        current = shape
    return current


LIPSYNC_ARGS = []


def lipsync_shapes(binary, wav, text_file, tsv):
    # At the rhubarb formats' default frame rate: 100, Rhubarb's 10 ms cues.
    command = [binary, "render", wav, "--format", "rhubarb-tsv", "--extended-shapes", "GHX", "-o", tsv]
    command += LIPSYNC_ARGS
    if text_file:
        command[3:3] = ["--text-file", text_file]
    run(command)
    return read_tsv(tsv)


def rhubarb_shapes(binary, wav, text_file, tsv):
    command = [binary, "-q", "-f", "tsv", "-o", tsv, wav]
    if text_file:
        command[1:1] = ["-d", text_file]
    run(command)
    return read_tsv(tsv)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lipsync", required=True)
    parser.add_argument("--rhubarb", required=True)
    parser.add_argument("--sentences", type=int, default=10)
    parser.add_argument("--misses", action="store_true", help="print each miss: speaker, sentence, phone, time, shape shown")
    parser.add_argument("--no-timing", action="store_true", help="skip the LibriVox wall-time runs")
    parser.add_argument("--lipsync-only", action="store_true", help="run lipsyncd only (for trying its settings)")
    parser.add_argument("--lipsync-args", default="", help="more arguments for lipsync render (space-separated)")
    args = parser.parse_args()
    LIPSYNC_ARGS.extend(args.lipsync_args.split())
    for tool in (args.lipsync, args.rhubarb):
        if not os.access(tool, os.X_OK):
            sys.exit(f"compare_rhubarb: {tool}: not an executable file")
    tools = {"lipsyncd": (args.lipsync, lipsync_shapes), "Rhubarb 1.14": (args.rhubarb, rhubarb_shapes)}
    if args.lipsync_only:
        del tools["Rhubarb 1.14"]
    speakers = {name: fn for name, fn in (("Festival", festival), ("flite", flite)) if shutil.which(name.lower())}
    work = tempfile.mkdtemp(prefix="compare_rhubarb-")
    # score[(tool, mode)][class] = [right, total]
    score = {}
    for speaker, speak in speakers.items():
        for n, text in enumerate(HARVARD[: args.sentences]):
            wav = os.path.join(work, f"{speaker}-{n}.wav")
            text_file = os.path.join(work, f"{speaker}-{n}.txt")
            with open(text_file, "w") as f:
                f.write(text + "\n")
            truth = speak(text, wav)
            for tool, (binary, shapes_of) in tools.items():
                for mode, transcript in (("audio only", None), ("with transcript", text_file)):
                    shapes = shapes_of(binary, wav, transcript, os.path.join(work, "out.tsv"))
                    for key in ((tool, mode, speaker), (tool, mode, "all")):
                        per_class = score.setdefault(key, {c: [0, 0] for c in CLASSES})
                        for name, start, end in truth:
                            for cls, (phones, wanted) in CLASSES.items():
                                if name in phones:
                                    per_class[cls][1] += 1
                                    shown = shape_at(shapes, (start + end) / 2)
                                    per_class[cls][0] += shown in wanted
                                    if args.misses and speaker == key[2] and shown not in wanted:
                                        print(f"miss: {tool}, {mode}, {speaker} {n + 1}: /{name}/ at {(start + end) / 2:.3f} s shows {shown}")
    print(f"| tool | mode | speech | " + " | ".join(CLASSES) + " |")
    print("|---|---|---|" + "---:|" * len(CLASSES))
    for (tool, mode, speaker), per_class in sorted(score.items(), key=lambda kv: (kv[0][2] != "all", kv[0])):
        cells = [f"{100 * r / max(1, t):.0f} % ({r}/{t})" for r, t in per_class.values()]
        print(f"| {tool} | {mode} | {speaker} | " + " | ".join(cells) + " |")

    if os.path.exists(LIBRIVOX) and not args.no_timing:
        text_file = os.path.join(work, "librivox.txt")
        with open(text_file, "w") as f:
            f.write(LIBRIVOX_TEXT + "\n")
        print(f"\nWall time on {os.path.basename(LIBRIVOX)} (7.1 s), best of 3:")
        for tool, (binary, shapes_of) in tools.items():
            for mode, transcript in (("audio only", None), ("with transcript", text_file)):
                best = 1e9
                for _ in range(3):
                    start = time.monotonic()
                    shapes_of(binary, LIBRIVOX, transcript, os.path.join(work, "out.tsv"))
                    best = min(best, time.monotonic() - start)
                print(f"  {tool:13s} {mode:16s} {best:5.2f} s")
    shutil.rmtree(work)


if __name__ == "__main__":
    main()
