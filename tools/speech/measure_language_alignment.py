#!/usr/bin/env python3
"""Measures `lipsync align --voice V` (DTW against espeak-ng's rendering) on Festival voices.

Festival speaks each sentence and writes its own segment times (utt.save.segs): the truth.
`lipsync align X.wav --text T --voice V` aligns the WAV; its phones (espeak-ng's IPA, or its
English mnemonics) are matched to Festival's by a Needleman-Wunsch alignment of the two
phone sequences after mapping both to a coarse key (Festival's SAMPA-like labels without
stress digits, IPA without length marks and diacritics; see phone_key), a geminate consonant
written as two phones in a row taken as one (scored_phones). A boundary is
scored when a phone and the one before it are matched on both sides (pauses excluded):
its error is |aligned start - Festival start|. A bilabial closure (/p b m/ matched to
/p b m/) counts as within 30 ms when the start is.

Festival's Russian voice (unit selection) labels some /p b m/ 50 to 85 ms after its own waveform
has closed: --label-check counts, per voice, the /p b m/ after a sound whose formant band level
(400-3500 Hz) is already 10 dB down, and stays down, before Festival's label; --acoustic-closures
scores the voices of ACOUSTIC_CLOSURE_VOICES against those closures measured on the samples
instead (only ever earlier than the label), as tests/speech/tts_recordings.hpp does for espeak-ng.

Usage: measure_language_alignment.py LIPSYNC_BINARY OUT_DIR [--voices it,ca,...] [--markdown]
       [--held-out] [--details] [--acoustic-closures | --label-check]
       measure_language_alignment.py LIPSYNC_BINARY OUT_DIR --corpus tests/data/recorded_languages
The second form (re)makes the test corpus: CORPUS_ITEMS spoken by Festival (NAME.wav), their
transcripts (NAME.txt, first line the espeak-ng voice) and NAME.truth.tsv, one line per
Festival segment the scoring matches: Festival's label and start (s), the index and label
of the aligned phone it is matched to (in the 'phones' tier of that recording's alignment,
pauses included: espeak-ng's phonemes for the text, less any short pause before a /p b/ that
the closure refiner gave to the stop), and its kind, a sum of 1 (its
start is a scored boundary: the phone before is matched too) and 2 (a bilabial closure). tests/languages/recorded_languages_test.cpp reads them.
"""
import argparse
import json
import math
import os
import re
import statistics
import struct
import subprocess
import sys
import wave

# Festival voice, espeak-ng voice, sentences (the same text for both).
VOICES = {
    "it": ("lp_diphone", "it", [
        "Buon giorno, come stai? Mi piace molto la pasta al pomodoro.",
        "Il bambino beve un bicchiere di latte freddo ogni mattina.",
        "Abbiamo perso il treno per Milano e siamo tornati a piedi.",
        "La mamma compra le mele rosse al mercato di Bologna.",
    ]),
    "ca": ("upc_ca_ona_hts", "ca", [
        "Bon dia, com estas? M'agrada molt el pa amb tomaquet.",
        "La mare compra pomes vermelles al mercat de Barcelona.",
        "El meu pare treballa en una biblioteca molt bonica.",
        "Obrim la porta i mirem el mar blau des de la platja.",
    ]),
    "fi": ("suo_fi_lj_diphone", "fi", [
        "Hyvaa huomenta, mita kuuluu? Minulla on kaunis punainen pallo.",
        "Isa osti uuden auton ja ajoi sen kotiin Helsingista.",
        "Poika juo maitoa ja syo leipaa aamulla ennen koulua.",
        "Meri on tanaan sininen ja tuuli puhaltaa lannesta.",
    ]),
    "cs": ("czech_dita", "cs", [
        "Dobrý den, jak se máte? Mám rád pivo a chleba.",
        "Maminka koupila modré boty a malou bílou tašku.",
        "Pojedeme vlakem do Brna a potom budeme pracovat.",
        "Bratr pije mléko a babička peče buchty.",
    ]),
    "ru": ("msu_ru_nsh_clunits", "ru", [
        "Доброе утро, как дела? Мама мыла раму.",
        "Папа купил большой белый автобус.",
        "Мы были в библиотеке и потом пошли домой.",
        "Бабушка пьёт молоко и ест пирог с мясом.",
    ]),
    "hi": ("hindi_NSK_diphone", "hi", [
        "नमस्ते, आप कैसे हैं?",
        "मेरा नाम भारत है और मैं बम्बई में रहता हूँ।",
        "बच्चे पानी पीते हैं और बाज़ार जाते हैं।",
        "पिताजी ने एक बड़ा मकान बनाया।",
    ]),
    "en": ("kal_diphone", "en-us", [
        "Bob may buy the blue boat in my harbour.",
        "The big brown dog jumped over a fence to be with me.",
        "Please pass me a map of the bay before we move.",
        "My mother ate apple pie from a paper plate.",
    ]),
}

# Sentences held out of every choice of the aligner's settings (six per voice), measured apart.
# The first two of each voice were the held-out set alone; the other four, each with several
# /p b m/ in varied places (after a vowel, a consonant, a nasal, a pause; before a stop), were
# written and committed before anything was measured on them. --sentences picks some by index.
HELD_OUT = {
    "it": ["Il babbo porta il bambino al parco dopo pranzo.",
           "Maria ha comprato un ombrello blu e una borsa nuova.",
           "Paolo mangia un panino con burro e marmellata.",
           "Bruno compra sempre pane bianco per la nonna.",
           "Domani mattina prendiamo il pullman per Parma.",
           "Le api volano sopra i campi pieni di papaveri."],
    "ca": ["El pastor porta les ovelles al bosc cada dia.",
           "Ma mare prepara un bon sopar per a tothom.",
           "Em poso el barret blau per anar a la platja.",
           "El meu amic Pere menja pomes i peres cada tarda.",
           "Avui la Maria ha comprat un pa molt bo.",
           "Les barques del port surten amb el bon temps."],
    "fi": ["Pekka ja Maija menivat puistoon pelaamaan palloa.",
           "Mummo paistoi pullaa ja kahvi oli kuumaa.",
           "Pappa ostaa kaupasta maitoa ja banaaneja.",
           "Minun ystavani Matti pelaa jalkapalloa puistossa.",
           "Ampiainen lensi ikkunasta sisaan ja pelotti meita.",
           "Omena ja mansikka ovat parempia kuin peruna."],
    "cs": ["Pavel má velmi pěkný byt v Praze.",
           "Na podzim padá listí a obloha je modrá.",
           "Petr a Marie běží pomalu po mostě.",
           "Máma dnes koupila mléko, máslo a pomeranče.",
           "V obchodě prodávají papír, pera a barevné tužky.",
           "Pan Novák bydlí v malém domě blízko parku."],
    "ru": ["Мой брат пишет письмо маме.",
           "Птицы поют в большом парке весной.",
           "Папин брат принёс большую банку мёда.",
           "Мы пошли в парк и встретили там бабушку.",
           "Мама купила помидоры, перец и хлеб.",
           "В апреле мы будем плавать в бассейне."],
    "hi": ["मैं पानी पीना चाहता हूँ।",
           "बाबा ने पुस्तक पढ़ी और फिर बाहर गए।",
           "बिल्ली ने मछली खाई और पानी पिया।",
           "मेरे पापा बाज़ार से आम लाए।",
           "हम सुबह पार्क में घूमने गए।",
           "माँ ने बच्चों के लिए मीठी पूरी बनाई।"],
    "en": ["Peter bought a bag of plums for my mom.",
           "Maybe the boy will bring a basket of apples.",
           "Paul lost his purple umbrella on the bus.",
           "My brother keeps a pet rabbit in a box.",
           "Pam made a lamp from an empty bottle.",
           "The baby sleeps by the open window most mornings."],
}

# Festival label (stress digits dropped) → IPA-like, before the coarse key.
FESTIVAL_TO_IPA = {
    "tS": "tʃ", "dZ": "dʒ", "S": "ʃ", "Z": "ʒ", "O": "ɔ", "E": "ɛ", "J": "ɲ", "L": "ʎ", "N": "ŋ",
    "ax": "ə", "@": "ə", "ts": "ts", "dz": "dz", "jj": "j", "rr": "r", "ll": "l", "nn": "n",
    # English "radio" phones
    "aa": "ɑ", "ae": "æ", "ah": "ʌ", "ao": "ɔ", "aw": "a", "ay": "a", "eh": "ɛ", "er": "ɜ", "ey": "e",
    "ih": "ɪ", "iy": "i", "ow": "o", "oy": "ɔ", "uh": "ʊ", "uw": "u", "ch": "tʃ", "jh": "dʒ",
    "sh": "ʃ", "zh": "ʒ", "th": "θ", "dh": "ð", "ng": "ŋ", "hh": "h", "hv": "h", "y": "j", "dx": "t",
    "axr": "ə", "el": "l", "em": "m", "en": "n", "nx": "n",
}
# espeak-ng's English mnemonics → IPA-like (the English voices' phone set).
ESPEAK_EN_TO_IPA = {
    "@": "ə", "3": "ɜ", "3:": "ɜ", "a": "æ", "aa": "ɑ", "A:": "ɑ", "A@": "ɑ", "E": "ɛ", "eI": "e", "I": "ɪ",
    "i": "i", "i:": "i", "O:": "ɔ", "O": "ɔ", "oU": "o", "U": "ʊ", "u:": "u", "V": "ʌ", "aI": "a", "aU": "a",
    "OI": "ɔ", "e@": "ɛ", "I@": "ɪ", "U@": "ʊ", "tS": "tʃ", "dZ": "dʒ", "S": "ʃ", "Z": "ʒ", "T": "θ", "D": "ð",
    "N": "ŋ", "r": "r", "r-": "r", "l": "l", "t#": "t", "d#": "d", "a#": "ə", "@L": "l", "i@": "i", "0": "ɒ",
    "I2": "ɪ", "I#": "ɪ", "@2": "ə", "@5": "ə", "n-": "n", "aI@": "a", "aI3": "a", "eI@": "e",
}
FOLD = {"ɾ": "r", "ɫ": "l", "ɡ": "g", "ʁ": "r", "ɹ": "r", "ɒ": "ɔ", "ɐ": "a", "ɑ": "a", "ʌ": "a", "æ": "a",
        "ɛ": "e", "ɪ": "i", "ʊ": "u", "ɨ": "i", "ɔ": "o", "ɜ": "ə", "ʋ": "v", "ʂ": "ʃ", "ʐ": "ʒ", "ç": "x",
        "ɦ": "h", "ɲ": "n", "ʎ": "l", "ŋ": "n", "ɳ": "n", "ʈ": "t", "ɖ": "d", "ɽ": "r", "ʒ": "ʃ", "ð": "d",
        "θ": "t", "ɣ": "g", "β": "b", "ɕ": "ʃ", "ʑ": "ʃ"}
VOWELS = set("aeiouyøœəɯɤɵʉ")
PAUSES = {"", "#", "pau", "h#", "brth", "_", "SIL", "sil"}


def phone_key(label, festival, english_espeak=False):
    """The coarse key of a label: one base symbol (vowels and consonants folded to broad classes)."""
    if festival:
        label = re.sub(r"[0-9]", "", label)
        label = FESTIVAL_TO_IPA.get(label, FESTIVAL_TO_IPA.get(label.lower(), label))
    elif english_espeak:
        label = ESPEAK_EN_TO_IPA.get(label, label)
    label = label.replace("ː", "").replace(":", "").replace("'", "").replace("ˈ", "").replace("ˌ", "")
    for c in label:
        if c.isalpha() or c in "əɛɔɪʊ":
            c = c.lower() if c.isascii() else c
            return FOLD.get(c, c)
    return label[:1]


def is_vowel(key):
    return key in VOWELS


def match_score(x, y):
    if x == y:
        return 3
    if is_vowel(x) and is_vowel(y):
        return 1
    if not is_vowel(x) and not is_vowel(y):
        return 0
    return -2


def needleman_wunsch(a, b, gap=-1):
    """Pairs (i, j) of matched positions of key lists a and b."""
    n, m = len(a), len(b)
    score = [[0] * (m + 1) for _ in range(n + 1)]
    for i in range(1, n + 1):
        score[i][0] = i * gap
    for j in range(1, m + 1):
        score[0][j] = j * gap
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            score[i][j] = max(score[i - 1][j - 1] + match_score(a[i - 1], b[j - 1]), score[i - 1][j] + gap,
                              score[i][j - 1] + gap)
    pairs, i, j = [], n, m
    while i > 0 and j > 0:
        if score[i][j] == score[i - 1][j - 1] + match_score(a[i - 1], b[j - 1]):
            pairs.append((i - 1, j - 1))
            i, j = i - 1, j - 1
        elif score[i][j] == score[i - 1][j] + gap:
            i -= 1
        else:
            j -= 1
    return pairs[::-1]


def read_festival_segs(path):
    """Festival's utt.save.segs: (label, start_s, end_s) after the '#' header line."""
    lines = open(path, encoding="utf-8", errors="replace").read().splitlines()
    body = lines[lines.index("#") + 1:]
    segments, start = [], 0.0
    for line in body:
        parts = line.split()
        if len(parts) < 3:
            continue
        end = float(parts[0])
        segments.append((parts[2], start, end))
        start = end
    return segments


def read_textgrid_phones(path):
    """The 'phones' tier of a long-format TextGrid: (label, start_s, end_s)."""
    text = open(path, encoding="utf-8").read()
    tier = text[text.index('name = "phones"'):]
    return [(label, float(xmin), float(xmax))
            for xmin, xmax, label in re.findall(r'xmin = ([0-9.]+)\s*xmax = ([0-9.]+)\s*text = "([^"]*)"', tier)]


# Festival's Czech reads ISO 8859-2 (UTF-8 letters come out as "neznámý", unknown), its Italian and
# Finnish ISO 8859-1 (a UTF-8 "ì" stops Italian's letter-to-sound rules; Finnish speaks a UTF-8
# "ä" as "a" and then words for an unknown character, "tuntematon merkki"); the others UTF-8.
FESTIVAL_ENCODING = {"czech_dita": "iso-8859-2", "lp_diphone": "iso-8859-1", "suo_fi_lj_diphone": "iso-8859-1"}


def speak_with_festival(festival_voice, text, wav, segs):
    escaped = text.replace("\\", "\\\\").replace('"', '\\"')
    encoding = FESTIVAL_ENCODING.get(festival_voice, "utf-8")
    command = ["festival", "-b", f"(voice_{festival_voice})", f'(set! u (SynthText "{escaped}"))',
               f'(utt.save.segs u "{segs}")', f'(utt.save.wave u "{wav}" "riff")']
    subprocess.run([c.encode(encoding) for c in command], check=True, capture_output=True, timeout=120)


def scored_phones(segments, festival, english_espeak=False):
    """The indices and keys of the phones scored: pauses left out, and a geminate consonant
    written as two phones in a row (espeak-ng's Finnish "Mummo" /m m/, where Festival has one
    /mː/) taken as one, at its first phone's start: its closure starts there."""
    indices, keys = [], []
    for k, (label, start, _) in enumerate(segments):
        if label in PAUSES:
            continue
        key = phone_key(label, festival, english_espeak)
        previous = indices[-1] if indices else None
        if (previous == k - 1 and keys[-1] == key and not is_vowel(key)
                and abs(segments[previous][2] - start) < 1e-3):
            continue
        indices.append(k)
        keys.append(key)
    return indices, keys


def boundary_errors(truth, aligned, english_espeak):
    """Errors (s) of the boundaries matched between Festival's segments and the aligner's
    phones, and of the bilabial closures; the pairs scored."""
    t_index, a = scored_phones(truth, True)
    a_index, b = scored_phones(aligned, False, english_espeak)
    truth = [truth[k] for k in t_index]
    aligned = [aligned[k] for k in a_index]
    pairs = needleman_wunsch(a, b)
    errors, bilabial = [], []
    previous = None
    for i, j in pairs:
        consecutive = previous == (i - 1, j - 1)
        previous = (i, j)
        if match_score(a[i], b[j]) < 0:
            continue
        error = abs(aligned[j][1] - truth[i][1])
        if a[i] in ("p", "b", "m") and b[j] in ("p", "b", "m"):
            bilabial.append(error)
            if DETAILS:
                print(f"  bilabial {'PAUSE' if i == 0 or truth[i - 1][2] < truth[i][1] - 1e-3 else truth[i - 1][0]:>5} {truth[i][0]:>4} truth {truth[i][1]:.3f} aligned {aligned[j][1]:.3f} "
                      f"error {1000 * (aligned[j][1] - truth[i][1]):+.0f} ms", file=sys.stderr)
        if consecutive:
            errors.append(error)
    return errors, bilabial


DETAILS = False

# Festival voices whose labels are not where their own waveform closes the lips: the Russian unit
# selection voice puts /p b m/ 50 to 85 ms after the formant band has fallen (its units' labels
# come from its database, not from the joined waveform; --label-check shows it per voice).
# --acoustic-closures scores these voices against the closures measured on the samples.
ACOUSTIC_CLOSURE_VOICES = {"ru"}
# A closure: the formant band's level this far under the phone before's (median of its first half's 10 ms levels).
CLOSURE_FALL_DB = 10.0
# How far before Festival's label a closure is looked for, ms.
CLOSURE_SEARCH_MS = 100


def band_energies(wav):
    """The energy of every millisecond of the WAV in the formant band (400-3500 Hz, two second-order
    Butterworth sections, as core/speech/src/closure_refiner.cpp filters it)."""
    with wave.open(wav) as w:
        rate, count = w.getframerate(), w.getnframes()
        samples = [v / 32768.0 for v in struct.unpack("<%dh" % count, w.readframes(count))]
    for hz, high in ((400.0, True), (min(3500.0, 0.45 * rate), False)):
        omega = 2 * math.pi * hz / rate
        alpha, c = math.sin(omega) / math.sqrt(2), math.cos(omega)
        k, b1 = ((1 + c) / 2, -(1 + c)) if high else ((1 - c) / 2, 1 - c)
        b0, b1, b2, a1, a2 = (v / (1 + alpha) for v in (k, b1, k, -2 * c, 1 - alpha))
        x1 = x2 = y1 = y2 = 0.0
        for i, x in enumerate(samples):
            y = b0 * x + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2
            x2, x1, y2, y1 = x1, x, y1, y
            samples[i] = y
    per_ms = rate // 1000
    return [sum(y * y for y in samples[k * per_ms:(k + 1) * per_ms]) / per_ms for k in range(len(samples) // per_ms)]


def level_db(energies, start_ms, end_ms=None):
    """The level (dB) of the 10 ms from start_ms, or of [start_ms, end_ms)."""
    span = energies[max(0, start_ms):min(len(energies), end_ms if end_ms else start_ms + 10)]
    return 10 * math.log10(max(1e-10, sum(span) / max(1, len(span))))


def is_bilabial_after_sound(truth, k):
    """Festival's segment k is a /p b m/ after a sound: not after a pause or a stop (whose closure is
    as quiet as the /p b m/)."""
    return (k > 0 and truth[k][0] not in PAUSES and truth[k - 1][0] not in PAUSES
            and phone_key(truth[k][0], True) in ("p", "b", "m") and phone_key(truth[k - 1][0], True) not in "ptkbdgc")


def acoustic_closures(truth, energies):
    """Festival's segments with each /p b m/ after a sound starting at its acoustic closure: the
    earliest millisecond, at most CLOSURE_SEARCH_MS before the label and after the phone before
    starts, from which every 10 ms level up to the label is CLOSURE_FALL_DB under the median
    level of the first half of the phone before (before any closing movement). A label with no such fall before it stays; none moves later. Also the moves (ms)."""
    result, moves = list(truth), []
    for k in range(1, len(truth)):
        label, start, end = truth[k]
        before = truth[k - 1]
        if not is_bilabial_after_sound(truth, k):
            continue
        label_ms, before_ms = int(round(start * 1000)), int(round(before[1] * 1000))
        half_ms = max(before_ms + 1, (before_ms + label_ms) // 2 - 10)
        reference = statistics.median(level_db(energies, t) for t in range(before_ms, half_ms))
        closure_ms = label_ms
        for t in range(label_ms, max(before_ms + 10, label_ms - CLOSURE_SEARCH_MS) - 1, -1):
            if level_db(energies, t) > reference - CLOSURE_FALL_DB:
                break
            closure_ms = t
        if closure_ms < label_ms:
            result[k - 1] = (before[0], before[1], closure_ms / 1000)
            result[k] = (label, closure_ms / 1000, end)
            moves.append(closure_ms - label_ms)
    return result, moves

# The test corpus: (voice code, sentence index) of VOICES.
CORPUS_ITEMS = [("it", 3), ("cs", 1), ("ca", 1), ("cs", 2), ("hi", 3), ("it", 1), ("fi", 2)]


def scored_pairs(truth, aligned, english_espeak=False):
    """(truth index, aligned index, kind) as boundary_errors scores them; indices into the full lists."""
    t_index, a = scored_phones(truth, True)
    a_index, b = scored_phones(aligned, False, english_espeak)
    result, previous = [], None
    for i, j in needleman_wunsch(a, b):
        consecutive = previous == (i - 1, j - 1)
        previous = (i, j)
        if match_score(a[i], b[j]) < 0:
            continue
        bilabial = a[i] in ("p", "b", "m") and b[j] in ("p", "b", "m")
        if consecutive or bilabial:
            result.append((t_index[i], a_index[j], (1 if consecutive else 0) + (2 if bilabial else 0)))
    return result


def make_corpus(lipsync, work_dir, corpus_dir):
    os.makedirs(corpus_dir, exist_ok=True)
    for code, k in CORPUS_ITEMS:
        festival_voice, espeak_voice, sentences = VOICES[code]
        sentence = sentences[k]
        name = f"{code}_{k}"
        base = os.path.join(corpus_dir, name)
        speak_with_festival(festival_voice, sentence, base + ".wav", os.path.join(work_dir, name + ".corpus.segs"))
        truth = read_festival_segs(os.path.join(work_dir, name + ".corpus.segs"))
        grid = os.path.join(work_dir, name + ".corpus.TextGrid")
        subprocess.run([lipsync, "align", base + ".wav", "--text", sentence, "--voice", espeak_voice, "-o", grid],
                       check=True)
        aligned = read_textgrid_phones(grid)
        with open(base + ".txt", "w", encoding="utf-8") as out:
            out.write(f"{espeak_voice}\n{sentence}\n")
        with open(base + ".truth.tsv", "w", encoding="utf-8") as out:
            out.write("# festival_label\tfestival_start_s\taligned_index\taligned_label\tkind\n")
            for i, j, kind in scored_pairs(truth, aligned):
                out.write(f"{truth[i][0]}\t{truth[i][1]:.4f}\t{j}\t{aligned[j][0]}\t{kind}\n")
        print(f"{name}: {len(truth)} Festival segments, {len(aligned)} aligned phones", file=sys.stderr)


def percentile(values, q):
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q * (len(ordered) - 1))))]


def sentences_of(code, held_out, picked=None):
    """Festival voice, espeak-ng voice, sentences (index, text) and file prefix of a voice's
    sentence set; picked: the indices to keep (all when None)."""
    festival_voice, espeak_voice, sentences = VOICES[code]
    prefix = code
    if held_out:
        sentences, prefix = HELD_OUT[code], code + "_held_out"
    chosen = [(k, s) for k, s in enumerate(sentences) if picked is None or k in picked]
    return festival_voice, espeak_voice, chosen, prefix


def festival_truth(festival_voice, sentence, base, acoustic):
    """Festival's segments of base.wav (spoken first if missing), with acoustic closures if asked."""
    if not os.path.exists(base + ".wav"):
        speak_with_festival(festival_voice, sentence, base + ".wav", base + ".segs")
    truth = read_festival_segs(base + ".segs")
    return acoustic_closures(truth, band_energies(base + ".wav"))[0] if acoustic else truth


def check_labels(args):
    """Per voice: the /p b m/ after a sound, how many start after their acoustic closure, by how much."""
    print("| Voice (Festival) | /p b m/ after a sound | label after the closure | median | largest |")
    print("|---|---|---|---|---|")
    for code in args.voices.split(","):
        festival_voice, _, sentences, prefix = sentences_of(code, args.held_out, args.sentences)
        count, moves = 0, []
        for k, sentence in sentences:
            base = os.path.join(args.out_dir, f"{prefix}_{k}")
            truth = festival_truth(festival_voice, sentence, base, False)
            count += sum(is_bilabial_after_sound(truth, i) for i in range(len(truth)))
            moves += acoustic_closures(truth, band_energies(base + ".wav"))[1]
        late = f"{statistics.median(moves):+.0f} ms | {min(moves):+.0f} ms" if moves else "– | –"
        print(f"| {code} ({festival_voice}) | {count} | {len(moves)} | {late} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("lipsync")
    parser.add_argument("out_dir")
    parser.add_argument("--voices", default=",".join(VOICES))
    parser.add_argument("--markdown", action="store_true", help="print the table for docs/languages.md")
    parser.add_argument("--corpus", help="make the test corpus in this directory instead")
    parser.add_argument("--held-out", action="store_true",
                        help="measure the held-out sentences (HELD_OUT) instead of the four of VOICES")
    parser.add_argument("--sentences", type=lambda v: {int(k) for k in v.split(",")},
                        help="only the sentences of these indices (0-based, comma-separated): "
                             "--held-out --sentences 0,1 is the first held-out pair")
    parser.add_argument("--details", action="store_true", help="print every bilabial closure's signed error")
    parser.add_argument("--acoustic-closures", action="store_true",
                        help="score ACOUSTIC_CLOSURE_VOICES against the closures measured on their samples")
    parser.add_argument("--label-check", action="store_true",
                        help="only print, per voice, how many /p b m/ labels start after the acoustic closure")
    args = parser.parse_args()
    global DETAILS
    DETAILS = args.details
    os.makedirs(args.out_dir, exist_ok=True)
    if args.corpus:
        make_corpus(args.lipsync, args.out_dir, args.corpus)
        return
    if args.label_check:
        check_labels(args)
        return
    rows = []
    for code in args.voices.split(","):
        festival_voice, espeak_voice, sentences, prefix = sentences_of(code, args.held_out, args.sentences)
        acoustic = args.acoustic_closures and code in ACOUSTIC_CLOSURE_VOICES
        aligners = [("dtw", ["--voice", espeak_voice, "--aligner", "dtw"])]
        if code == "en":
            aligners.append(("pocketsphinx", []))
        for aligner, options in aligners:
            errors, bilabial, failures = [], [], 0
            for k, sentence in sentences:
                base = os.path.join(args.out_dir, f"{prefix}_{k}")
                if DETAILS:
                    print(f"{prefix}_{k} {aligner}", file=sys.stderr)
                truth = festival_truth(festival_voice, sentence, base, acoustic)
                grid = f"{base}.{aligner}.TextGrid"
                run = subprocess.run([args.lipsync, "align", base + ".wav", "--text", sentence, "-o", grid] + options,
                                     capture_output=True, text=True)
                if run.returncode != 0:
                    print(f"{code} {k} {aligner}: {run.stderr.strip()}", file=sys.stderr)
                    failures += 1
                    continue
                aligned = read_textgrid_phones(grid)
                if aligner == "pocketsphinx":
                    aligned = [(l.lower(), s, t) for l, s, t in aligned]
                e, b = boundary_errors(truth, aligned, english_espeak=(code == "en" and aligner == "dtw"))
                errors += e
                bilabial += b
            row = {
                "voice": code + (" acoustic closures" if acoustic else ""), "festival": festival_voice, "espeak": espeak_voice, "aligner": aligner,
                "sentences": len(sentences), "failures": failures, "boundaries": len(errors),
                "median_ms": 1000 * statistics.median(errors) if errors else None,
                "p95_ms": 1000 * percentile(errors, 0.95) if errors else None,
                "bilabials": len(bilabial),
                "bilabial_within_30ms_pct": 100.0 * sum(e <= 0.030 for e in bilabial) / len(bilabial) if bilabial else None,
            }
            rows.append(row)
            print(json.dumps(row), file=sys.stderr)
    if args.markdown:
        print("| Voice (Festival) | espeak-ng voice | aligner | boundaries | median | p95 | bilabials within 30 ms |")
        print("|---|---|---|---|---|---|---|")
        for r in rows:
            fmt = lambda v, unit="": "–" if v is None else f"{v:.0f}{unit}"
            print(f"| {r['voice']} ({r['festival']}) | {r['espeak']} | {r['aligner']} | {r['boundaries']} | "
                  f"{fmt(r['median_ms'], ' ms')} | {fmt(r['p95_ms'], ' ms')} | "
                  f"{fmt(r['bilabial_within_30ms_pct'], ' %')} ({r['bilabials']}) |")
    json.dump(rows, open(os.path.join(args.out_dir, "results.json"), "w"), indent=1)


if __name__ == "__main__":
    main()
