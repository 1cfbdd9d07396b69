#!/usr/bin/env python3
"""Regenerates the language corpus: espeak-ng's own phoneme timings in several languages.

Each sentence is spoken by espeak-ng's C library (libespeak-ng, the library `lipsync say` uses),
initialised with espeakINITIALIZE_PHONEME_IPA so that its phoneme events carry IPA symbols; each
event's sample position is the phoneme's start, the next event's its end, as in
core/speech/src/synthesizer.cpp. The phonemes are written as a Praat TextGrid (one "phones"
tier, IPA labels as espeak-ng names them, stress marks and all), read back by the tests without a
phone-set flag: detection must pick the ipa set.

tests/languages/languages_test.cpp checks them through the whole path (closures sealed at
bilabial key frames, front rounded vowels puckered more than their unrounded partners, open vowels
open, nasal vowels open like their oral partners, bilabial fricatives near but not sealed).

Usage: python3 tests/data/languages/regenerate.py   (needs libespeak-ng1 and espeak-ng-data;
commit the results). The output depends on espeak-ng's version (1.51 in Debian 12).
"""

import ctypes
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

# file stem: (voice, sentence). Chosen for the contrasts the tests measure.
SENTENCES = {
    "fr_lune": ("fr", "Une lune, une île, du riz et du jus. Le bon vin blanc du pont, la bonne pomme, la "
                      "veine. Un peu de beurre, deux bœufs et ma petite sœur."),
    "de_bruecke": ("de", "Die Brücke über dem Fluss ist schön. Bücher und Bieter, Mütter und Mitte, "
                         "Höhle und Hehle. Pferde am Bach."),
    "es_haba": ("es", "La haba y el lobo. Bebe vino en Barcelona. Papá compra bombones."),
    "sv_fyra": ("sv", "Fyra nya byxor. Sju sköna hus. Mamma bakar bröd."),
    "pt_mae": ("pt", "A mãe e o pão. Bom dia, um bom vinho branco."),
    "ru_mama": ("ru", "Мама мыла раму. Папа был в Москве."),
    "ja_fuji": ("ja", "ふじさん。ぶぶん。"),
    "el_mpala": ("el", "Η μπάλα είναι μπλε. Καλημέρα, πώς είσαι;"),
}

# MFA's IPA phone sets (english_mfa, german_mfa, french_mfa, spanish_mfa 2.x dictionaries): words and
# then the phones each model has beyond them, diacritics and affricates included, 80 ms apiece (the
# tests render them; the timings are not an aligner's).
MFA_PHONES = {
    "mfa_english": "spn p ɑ p ə b ɔ t f aj v b ɪ ɡ m æ p s sil tʰ ɛ ɫ ɚ ɾ ej dʒ ow aw ç uː ʉː m̩ n̩ ɫ̩ c ɟ ʎ ɲ kʷ "
                   "θ ð ʃ ʒ ŋ ɹ w j z ɐ ɒ ɜː ɔj tʃ ɑː i iː ʊ",
    "mfa_german": "ɡ uː t ə n m ɔ ʁ ɡ ə n sil pf eː ɐ d ə yː b ɐ b ʁ ʏ k ŋ̩ sil ç x ts aj aw ɔʏ øː œ ʔ tʃ ɛː ɪ ʊ "
                  "cʰ kʰ pʰ tʰ l̩ m̩ ʃ s z v f h j a aː o oː ɛ e iː",
    "mfa_french": "œ̃ b ɔ̃ v ɛ̃ b l ɑ̃ sil y n f l œ ʁ d ø ɥ i ʃ ʒ ɲ ŋ tʃ dʒ ə ɛ e o ɔ a ɑ m p t k ɡ s z v w j u",
    "mfa_spanish": "ɟʝ o l a a β a e l p e r o sil x θ ʎ ɲ ɾ ð ɣ tʃ ʝ w j i u m n b d ɡ f s t k ç ts",
}

EVENT_PHONEME = 7  # espeakEVENT_PHONEME
EVENT_LIST_TERMINATED = 0


class Event(ctypes.Structure):
    _fields_ = [("type", ctypes.c_int), ("unique_identifier", ctypes.c_uint), ("text_position", ctypes.c_int),
                ("length", ctypes.c_int), ("audio_position", ctypes.c_int), ("sample", ctypes.c_int),
                ("user_data", ctypes.c_void_p), ("id", ctypes.c_char * 8)]


def synthesize(lib, voice, text):
    samples = [0]
    events = []

    @ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.POINTER(Event))
    def callback(wav, count, event_list):
        if wav and count > 0:
            samples[0] += count
        i = 0
        while event_list[i].type != EVENT_LIST_TERMINATED:
            if event_list[i].type == EVENT_PHONEME:
                events.append((event_list[i].id.decode("utf-8", "replace"), event_list[i].sample))
            i += 1
        return 0

    lib.espeak_SetSynthCallback(callback)
    if lib.espeak_SetVoiceByName(voice.encode()) != 0:
        sys.exit("unknown voice " + voice)
    data = text.encode("utf-8") + b"\0"
    lib.espeak_Synth(data, len(data), 0, 1, 0, 1, None, None)  # POS_CHARACTER, espeakCHARS_UTF8
    lib.espeak_Synchronize()
    return events, samples[0]


def textgrid(phones, end_s):
    lines = ['File type = "ooTextFile"', 'Object class = "TextGrid"', "", "xmin = 0", "xmax = %s" % end_s,
             "tiers? <exists>", "size = 1", "item []:", "    item [1]:", '        class = "IntervalTier"',
             '        name = "phones"', "        xmin = 0", "        xmax = %s" % end_s,
             "        intervals: size = %d" % len(phones)]
    for i, (label, start, end) in enumerate(phones, 1):
        lines += ["        intervals [%d]:" % i, "            xmin = %s" % start, "            xmax = %s" % end,
                  '            text = "%s"' % label.replace('"', '""')]
    return "\n".join(lines) + "\n"


def main():
    lib = ctypes.CDLL("libespeak-ng.so.1")
    rate = lib.espeak_Initialize(2, 0, None, 0x0001 | 0x0002 | 0x8000)  # SYNCHRONOUS; PHONEME_EVENTS|IPA|DONT_EXIT
    if rate <= 0:
        sys.exit("cannot initialise espeak-ng")
    for stem, (voice, text) in SENTENCES.items():
        events, total = synthesize(lib, voice, text)
        phones = []
        for i, (name, sample) in enumerate(events):
            end = events[i + 1][1] if i + 1 < len(events) else total
            start = max(sample, phones[-1][2] if phones else 0)
            if end <= start:
                continue
            if name.startswith("(") and name.endswith(")"):
                name = ""  # a switch to another language's phonemes
            phones.append((name, start, end))
        if phones and phones[0][1] > 0:
            phones.insert(0, ("", 0, phones[0][1]))
        # Seconds with six decimals: whole microseconds, as the readers round them.
        seconds = [(label, "%.6f" % (start / rate), "%.6f" % (end / rate)) for label, start, end in phones]
        with open(os.path.join(HERE, stem + ".TextGrid"), "w", encoding="utf-8", newline="\n") as f:
            f.write(textgrid(seconds, "%.6f" % (total / rate)))
        print("wrote %s.TextGrid (%s, %d phones)" % (stem, voice, len(phones)))
    for stem, phones in MFA_PHONES.items():
        labels = phones.split()
        rows = [(label, "%.2f" % (0.08 * i), "%.2f" % (0.08 * (i + 1))) for i, label in enumerate(labels)]
        with open(os.path.join(HERE, stem + ".TextGrid"), "w", encoding="utf-8", newline="\n") as f:
            f.write(textgrid(rows, "%.2f" % (0.08 * len(labels))))
        print("wrote %s.TextGrid (%d phones)" % (stem, len(labels)))


if __name__ == "__main__":
    main()
