#!/usr/bin/env python3
"""The English phone loop on other languages: lipsyncd's live and offline audio-only paths on
Festival's Italian, Finnish and Czech voices.

Without a transcript both paths hear phones with PocketSphinx's English model: the live path
(Listen, `lipsync listen`) with its phone loop, the offline one (`lipsync render X.wav`) with
the English words it recognises, aligned, or its phone loop where they do not fit. This measures
what that is worth on speech in other languages. Festival speaks SENTENCES (twelve natural
sentences per language, rich in /p b m/, /f v/ and /a/) with lp_diphone (Italian),
suo_fi_lj_diphone (Finnish) and czech_dita (Czech) and writes its segment relation (start and end
of every phone it spoke): the truth (measure_language_alignment.py's speak_with_festival and
read_festival_segs). Festival's labels become IPA through measure_language_alignment.py's
FESTIVAL_TO_IPA with each language's own labels over it (FESTIVAL_IPA_OVERRIDES: Finnish "y" is
the vowel, "@" is ä; Czech "ch" is /x/, "c~" is č...); a label neither names is an error.

Each WAV goes, as a user sends it, to:

  live, audio alone       `lipsync listen WAV --pace realtime --latency-ms 200` against a lipsyncd
                          this tool starts (--lipsyncd, on a free port), one stream at a time
  live, transcript        the same with `--text-file T --voice V` (espeak-ng voice it, fi, cs: the
                          live warp against espeak-ng's rendering, docs/languages.md)
  live, words one at a time
                          the same with `--word-times MARKS --voice V` instead of the transcript:
                          the sentence's words as a TTS's word marks (Amazon Polly's JSON lines),
                          each at the start Festival gave its first segment, so `lipsync listen`
                          sends each word a second before the audio reaches it
  offline, audio alone    `lipsync render WAV`
  offline, transcript     `lipsync render WAV --text-file T --voice V` (espeak-ng voice it, fi, cs:
                          the DTW aligner of docs/languages.md), what a non-English user should use
  Festival's phones       `lipsync render PHONES.json --phone-set ipa`: Festival's own timed
                          phones in IPA, the best any recogniser could give

all with `--format visemes-oculus`, and each is scored as compare_headaudio.py scores English
(its Tally): at the middle of every reference phone of three classes, /p b m/ must show the
Oculus viseme PP, /f v/ FF (with Finnish's labiodental approximant /ʋ/, which Festival writes
"v", and Italian's /ɱ/, its "nf" before /f v/), /a/ aa (with Finnish /æ/, written ä; lipsyncd
shows /a æ/ as aa, as English /aa ae ah/). The live rows also give the latency `lipsync listen`
prints for each run (per frame, from the sending of the 20 ms piece that holds its time to the
frame's arrival): the median over the runs of each run's median and 95th percentile, and the
worst run's 95th percentile.

--pace asap is quicker, but its frames are not those a live voice gets: the server decodes the
audio that waited for it in larger pieces, so its guesses see further.

Outside the build and CI. Needs festival with festvox-italp16k, festvox-suopuhe-lj and
festvox-czech-dita (Debian); about 8 minutes on two cores (real-time pace takes the audio's
duration, 2 minutes for the 36 sentences, for each of the three live paths).
Usage: tools/speech/measure_live_languages.py --lipsync build/clients/cli/lipsync
       --lipsyncd build/server/lipsyncd [--languages it,fi,cs] [--pace realtime|asap]
       [--latency-ms 200] [--misses] [--keep DIR]
"""
import argparse
import json
import os
import re
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile

# Beside this script: the scoring of compare_headaudio.py, Festival's voices and labels of
# measure_language_alignment.py.
from compare_headaudio import Recording, Tally, read_viseme_steps
from measure_language_alignment import (FESTIVAL_ENCODING, FESTIVAL_TO_IPA, PAUSES, VOICES, read_festival_segs,
                                        speak_with_festival)

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "support"))
from listening_address import ServerProcess  # noqa: E402

# Natural sentences, twelve per language, each with several /p b m/, /f v/ and /a/.
SENTENCES = {
    "it": [
        "Il babbo ha comprato un vaso di fiori per la mamma.",
        "Ogni venerdì Fabio va al mare con la barca a vela.",
        "Paola beve un bicchiere di vino bianco dopo il lavoro.",
        "La bambina ha visto una farfalla bianca nel prato.",
        "Il fornaio prepara il pane fresco prima dell'alba.",
        "Mamma, posso avere un panino con burro e marmellata?",
        "Federico abita in una bella casa vicino al parco.",
        "Marco fa sempre una passeggiata dopo la cena.",
        "Il vento forte ha fatto volare via il cappello di Valeria.",
        "Abbiamo mangiato pasta al forno e frutta fresca.",
        "Perché non vieni a ballare con noi sabato sera?",
        "Mia sorella Fabiana lavora in farmacia a Verona.",
    ],
    "fi": [
        "Isä ja äiti ostivat uuden auton viime viikolla.",
        "Pekka pelaa palloa puistossa koko päivän.",
        "Mummo paistoi meille mustikkapiirakkaa.",
        "Tänään on kaunis ja lämmin kesäpäivä.",
        "Vanha mies kävelee hitaasti pitkin rantaa.",
        "Me menemme bussilla Helsinkiin huomenna aamulla.",
        "Poika juo maitoa ja syö leipää ja voita.",
        "Vesi on kylmää, mutta sauna on lämmin.",
        "Maija maalasi vanhan veneen valkoiseksi.",
        "Kahvi ja pulla maistuvat hyvältä aamupäivällä.",
        "Fanni opiskelee fysiikkaa ja filosofiaa.",
        "Minä pidän marjoista, omenoista ja banaaneista.",
    ],
    "cs": [
        "Maminka peče buchty a babička vaří polévku.",
        "Pavel bydlí v malém bytě v Praze.",
        "Vlak do Brna pojede v pět hodin ráno.",
        "Přes pole běží malý pes a hledá míč.",
        "Máme rádi pivo, víno a dobré jídlo.",
        "Večer jsme byli v divadle na pěkné hře.",
        "Bára koupila modrý svetr a bílé boty.",
        "Filip fotografuje vodopády a vysoké hory.",
        "Na podzim padá listí a fouká vítr.",
        "Pan Novák má velkou zahradu plnou ovoce.",
        "Babička nám upekla voňavý makový koláč.",
        "Po obědě půjdeme s Petrem na procházku do parku.",
    ],
}
LANGUAGE_NAMES = {"it": "Italian", "fi": "Finnish", "cs": "Czech"}

# Each voice's labels that FESTIVAL_TO_IPA (English radio names and Italian's SAMPA) does not
# name, or names otherwise (finnish_phones.scm, czech.scm, italian_phoneset.scm).
FESTIVAL_IPA_OVERRIDES = {
    "it": {"nf": "ɱ", "ng": "ŋ"},
    "fi": {"y": "y", "@": "æ", "7": "ø", "&": "ə", "T": "θ", "D": "ð", "L": "l", "N": "ŋ"},
    "cs": {"c": "ts", "c~": "tʃ", "ch": "x", "d~": "ɟ", "t~": "c", "n~": "ɲ", "n*": "ŋ", "dz~": "dʒ",
           "s~": "ʃ", "z~": "ʒ", "r~": "r̝", "r~*": "r̝̥", "h": "ɦ", "_": "ʔ"},  # "_": the glottal stroke between vowels
}
# Letters that are IPA as Festival writes them in these voices.
PLAIN_IPA = set("aeioubdfghjklmnprstvwz") | {"dz", "ts"}

CLASSES = {  # IPA (length and stress removed) -> the Oculus viseme that shows it
    "/p b m/ shown PP": ({"p", "b", "m"}, "PP"),
    "/f v/ shown FF": ({"f", "v", "ʋ", "ɱ"}, "FF"),
    "/a/ shown aa": ({"a", "æ"}, "aa"),
}
LATENCY = re.compile(r"latency from the end of the piece holding a frame's time to its arrival: "
                     r"p50 ([0-9.]+) ms, p95 ([0-9.]+) ms, max ([0-9.]+) ms over (\d+) frames")


def festival_ipa(code, label):
    """Festival's label (stress digit and length ':' as written) as IPA; '' for a pause."""
    if label in FESTIVAL_IPA_OVERRIDES[code]:
        return FESTIVAL_IPA_OVERRIDES[code][label]
    if label in PAUSES or label == "##":
        return ""
    base, long = re.sub(r"(?<=.)[0-9]$", "", label), ""  # Italian's stress; Finnish's ö is "7"
    if base.endswith(":") and len(base) > 1:
        base, long = base[:-1], "ː"
    ipa = FESTIVAL_IPA_OVERRIDES[code].get(base) or FESTIVAL_TO_IPA.get(base) or (base if base in PLAIN_IPA else None)
    if ipa is None:
        raise RuntimeError(f"Festival's {LANGUAGE_NAMES[code]} label '{label}' has no IPA here (FESTIVAL_IPA_OVERRIDES)")
    return ipa + long


def class_label(ipa):
    """The label a class lists: IPA without its length mark."""
    return ipa.replace("ː", "")


def festival_word_starts(festival_voice, text):
    """Where Festival starts each word of `text`, s: its first syllable's first segment (Festival
    speaks deterministically, so these are the times of the WAV speak_with_festival wrote)."""
    escaped = text.replace("\\", "\\\\").replace('"', '\\"')
    encoding = FESTIVAL_ENCODING.get(festival_voice, "utf-8")
    command = ["festival", "-b", f"(voice_{festival_voice})", f'(set! u (SynthText "{escaped}"))',
               '(mapcar (lambda (w) (format t "%s %f\\n" (item.name w) '
               '(item.feat w "R:SylStructure.daughter1.daughter1.segment_start"))) (utt.relation.items u (quote Word)))']
    spoken = subprocess.run([c.encode(encoding) for c in command], check=True, capture_output=True, timeout=120)
    return [float(line.split()[-1]) for line in spoken.stdout.decode(encoding).splitlines() if line.strip()]


def speak(code, number, text, work):
    """Festival speaks `text`: the WAV, the transcript file, its words as timed marks, Festival's
    phones in IPA [(ipa, start_s, end_s)] and the utterance JSON of those phones."""
    stem = os.path.join(work, f"{code}-{number}")
    try:
        speak_with_festival(VOICES[code][0], text, stem + ".wav", stem + ".segs")
    except subprocess.CalledProcessError as error:
        raise RuntimeError(f"festival ({VOICES[code][0]}) failed on \"{text}\": "
                           f"{error.stderr.decode(errors='replace').strip()[-400:]}") from error
    phones = [(festival_ipa(code, label), start, end) for label, start, end in read_festival_segs(stem + ".segs")]
    with open(stem + ".txt", "w", encoding="utf-8") as f:
        f.write(text + "\n")
    words, starts = text.split(), festival_word_starts(VOICES[code][0], text)
    if len(starts) != len(words):
        raise RuntimeError(f"Festival spoke {len(starts)} words of the {len(words)} in \"{text}\"")
    with open(stem + ".marks", "w", encoding="utf-8") as f:
        for word, start in zip(words, starts):
            f.write(json.dumps({"time": round(start * 1000), "type": "word", "start": 0, "end": 0, "value": word},
                               ensure_ascii=False) + "\n")
    with open(stem + ".phones.json", "w", encoding="utf-8") as f:
        json.dump({"phone_set": "ipa", "text": text,
                   "phonemes": [{"label": ipa, "start": start, "end": end} for ipa, start, end in phones]},
                  f, ensure_ascii=False, indent=1)
    return stem, phones


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n".join(__doc__.splitlines()[1:]))
    parser.add_argument("--lipsync", required=True, help="the lipsync CLI")
    parser.add_argument("--lipsyncd", required=True, help="the lipsyncd server, started here on a free port")
    parser.add_argument("--languages", default="it,fi,cs", help="of it, fi, cs (default: all three)")
    parser.add_argument("--pace", choices=("realtime", "asap"), default="realtime",
                        help="lipsync listen's --pace (default realtime: the latency a user sees)")
    parser.add_argument("--latency-ms", type=int, default=200, help="lipsync listen's --latency-ms (default 200)")
    parser.add_argument("--misses", action="store_true", help="print each miss: path, language, phone, time, viseme shown")
    parser.add_argument("--keep", metavar="DIR", help="write the WAVs, phones and every output to DIR and keep them")
    args = parser.parse_args()
    languages = [code for code in args.languages.split(",") if code]
    for code in languages:
        if code not in SENTENCES:
            sys.exit(f"measure_live_languages: --languages: unknown language {code} (it, fi, cs)")
    for binary in (args.lipsync, args.lipsyncd):
        if not os.access(binary, os.X_OK):
            sys.exit(f"measure_live_languages: {binary}: not an executable file")
    if not shutil.which("festival"):
        sys.exit("measure_live_languages: festival is not installed")

    work = args.keep or tempfile.mkdtemp(prefix="measure_live_languages-")
    os.makedirs(work, exist_ok=True)
    load_before = os.getloadavg()[0]  # other work on the machine delays the live frames
    try:
        server = ServerProcess([args.lipsyncd, "--listen", "127.0.0.1:0", "--log-level", "warn"])
    except RuntimeError as error:
        sys.exit(f"measure_live_languages: {error}")
    live = f"live, audio alone, {args.latency_ms} ms"
    live_transcript = f"live, transcript, {args.latency_ms} ms"
    live_words = f"live, words one at a time, {args.latency_ms} ms"
    visemes = ["--format", "visemes-oculus"]
    listen = lambda stem: [args.lipsync, "listen", stem + ".wav", "--server", server.address, "--pace", args.pace,
                           "--latency-ms", str(args.latency_ms)]
    paths = {  # path -> f(language code, file stem) -> its command, less `-o OUT`
        live: lambda code, stem: listen(stem) + visemes,
        live_transcript: lambda code, stem: listen(stem) + ["--text-file", stem + ".txt", "--voice", VOICES[code][1]]
                                            + visemes,
        live_words: lambda code, stem: listen(stem) + ["--word-times", stem + ".marks", "--voice", VOICES[code][1]]
                                       + visemes,
        "offline, audio alone": lambda code, stem: [args.lipsync, "render", stem + ".wav"] + visemes,
        "offline, transcript": lambda code, stem: [args.lipsync, "render", stem + ".wav", "--text-file", stem + ".txt",
                                                   "--voice", VOICES[code][1]] + visemes,
        "Festival's phones": lambda code, stem: [args.lipsync, "render", stem + ".phones.json", "--phone-set", "ipa"]
                                                + visemes,
    }
    tally = Tally(CLASSES)
    latencies = {}  # latencies[(language, path)] = [(p50_ms, p95_ms)] per live run
    try:
        for code in languages:
            language = LANGUAGE_NAMES[code]
            for number, text in enumerate(SENTENCES[code], 1):
                stem, phones = speak(code, number, text, work)
                scored = Recording(language, str(number), stem + ".wav", stem + ".txt",
                                   [(class_label(ipa), start, end) for ipa, start, end in phones])
                for path, command_of in paths.items():
                    out = f"{stem}.{re.sub(r'[^A-Za-z0-9]+', '_', path).strip('_')}.json"
                    command = command_of(code, stem) + ["-o", out]
                    result = subprocess.run(command, capture_output=True, text=True)
                    if result.returncode != 0:
                        raise RuntimeError(f"{shlex.join(command)} failed ({result.returncode}): {result.stderr.strip()[-400:]}")
                    if path in (live, live_transcript, live_words):
                        with open(out + ".stderr", "w", encoding="utf-8") as f:
                            f.write(result.stderr)
                        found = LATENCY.search(result.stderr)
                        if found:
                            latencies.setdefault((language, path), []).append(
                                (float(found.group(1)), float(found.group(2))))
                    tally.score(path, scored, read_viseme_steps(out), args.misses)
            print(f"{language}: {len(SENTENCES[code])} sentences", file=sys.stderr)
    finally:
        server.stop()
        if not args.keep:
            shutil.rmtree(work)

    print(f"Shown / total at the middles of Festival's phones; live: lipsync listen --pace {args.pace}; "
          f"load average {load_before:.1f} before, {os.getloadavg()[0]:.1f} after ({os.cpu_count()} cores)\n")
    print("| language | path | latency p50 / p95 (worst run's p95) | " + " | ".join(CLASSES) + " |")
    print("|---|---|---|" + "---:|" * len(CLASSES))
    for code in languages:
        language = LANGUAGE_NAMES[code]
        for path in paths:
            if latencies.get((language, path)):
                runs = latencies[(language, path)]
                latency = (f"{statistics.median(p50 for p50, _ in runs):.0f} / "
                           f"{statistics.median(p95 for _, p95 in runs):.0f} ms ({max(p95 for _, p95 in runs):.0f})")
            else:
                latency = "–" if path in (live, live_transcript, live_words) else "(whole file)"
            name = f"{path}, `--voice {VOICES[code][1]}`" if "transcript" in path or "words" in path else path
            print(f"| {language} | {name} | {latency} | " + " | ".join(tally.cells(language, path)) + " |")
    if args.misses:
        tally.print_shown_instead()


if __name__ == "__main__":
    try:
        main()
    except RuntimeError as error:  # Festival, lipsync or lipsyncd failed: its command and message
        sys.exit(f"measure_live_languages: {error}")
