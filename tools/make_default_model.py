#!/usr/bin/env python3
"""Derives lipsyncd's default articulation model from phonetic features.

The model (data/models/default.json, schema in docs/model.md) gives every
phoneme of the inventory a target and a Cohen-Massaro dominance function per
articulator channel. Nothing in it is typed in by hand: each phoneme is
described by its phonetic features (height, backness, rounding for vowels;
place, manner, voicing for consonants) in the tables below, and the rules
further down turn features into targets and dominance parameters. Change a
feature or a rule here, run this script, and commit the regenerated files.

The same script writes the phone-set tables (data/phonesets/*.json), their
documentation (docs/phone-sets.md) and the model fixtures of the validation
tests (tests/data/models/*.json), so that everything derived stays in step.

Usage:
    python3 tools/make_default_model.py           # write all generated files
    python3 tools/make_default_model.py --check   # exit 1 if any file differs

Python 3 standard library only; the output is deterministic (no time stamps,
no set or hash ordering).
"""

import argparse
import json
import math
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# ---------------------------------------------------------------------------
# Channels: the articulators of the physics face (Kähler, Haber & Seidel 2001).
# ---------------------------------------------------------------------------

MUSCLE = "normalised contraction, 0 relaxed .. 1 strongest contraction used in speech"

CHANNELS = [
    # name, kind, min, max, rest, description
    ("zygomaticus_major_left", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; pulls the left mouth corner up and back (smile, spread /i/)"),
    ("zygomaticus_major_right", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; pulls the right mouth corner up and back (smile, spread /i/)"),
    ("levator_labii_superioris_left", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; raises the left upper lip, baring the upper teeth (/f v/, /sh/)"),
    ("levator_labii_superioris_right", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; raises the right upper lip, baring the upper teeth (/f v/, /sh/)"),
    ("risorius_left", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; pulls the left mouth corner sideways (lip spreading)"),
    ("risorius_right", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; pulls the right mouth corner sideways (lip spreading)"),
    ("depressor_anguli_oris_left", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; pulls the left mouth corner down"),
    ("depressor_anguli_oris_right", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; pulls the right mouth corner down"),
    ("depressor_labii_inferioris_left", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; pulls the left half of the lower lip down (open vowels, /th/)"),
    ("depressor_labii_inferioris_right", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; pulls the right half of the lower lip down (open vowels, /th/)"),
    ("mentalis", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; raises the chin and pushes the lower lip up (bilabial closure, /f v/)"),
    ("orbicularis_oris_upper", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; upper half of the lip sphincter: rounds, protrudes and closes the upper lip"),
    ("orbicularis_oris_lower", "muscle", 0.0, 1.0, 0.0,
     MUSCLE + "; lower half of the lip sphincter: rounds, protrudes and closes the lower lip, "
     "draws it in under the upper teeth for /f v/"),
    ("jaw_rotation", "jaw", 0.0, 1.0, 0.02,
     "jaw rotation about the temporomandibular axis: 0 teeth together, 1 the widest speech "
     "opening (about 20 degrees); rest 0.02 (teeth just apart)"),
    ("tongue_raise", "tongue", -1.0, 1.0, 0.0,
     "rigid tongue rotation relative to the jaw: -1 lowered to the floor of the mouth, "
     "0 rest, 1 tip/blade against the alveolar ridge or palate"),
    ("tongue_protrusion", "tongue", 0.0, 1.0, 0.0,
     "tongue tip position: 0 behind the teeth, 1 out between the teeth as for /th/"),
]
CHANNEL_NAMES = [c[0] for c in CHANNELS]
REST = {c[0]: c[4] for c in CHANNELS}
RANGE = {c[0]: (c[2], c[3]) for c in CHANNELS}

# Channel groups the rules talk about. Left and right are always set together:
# speech is symmetric in this model.
SMILE = ["zygomaticus_major_left", "zygomaticus_major_right"]
UPPER_LIP_RAISE = ["levator_labii_superioris_left", "levator_labii_superioris_right"]
SPREAD = ["risorius_left", "risorius_right"]
CORNER_DOWN = ["depressor_anguli_oris_left", "depressor_anguli_oris_right"]
LOWER_LIP_DOWN = ["depressor_labii_inferioris_left", "depressor_labii_inferioris_right"]
CHIN = ["mentalis"]
SPHINCTER = ["orbicularis_oris_upper", "orbicularis_oris_lower"]
LIP_SEAL = SPHINCTER + CHIN          # the channels that close the lips
ROUNDING = SPHINCTER + CHIN          # the channels that round and protrude them
LIPS = SMILE + UPPER_LIP_RAISE + SPREAD + CORNER_DOWN + LOWER_LIP_DOWN + CHIN + SPHINCTER
JAW = ["jaw_rotation"]
TONGUE = ["tongue_raise", "tongue_protrusion"]
assert sorted(LIPS + JAW + TONGUE) == sorted(CHANNEL_NAMES)

# Dominance defaults (Eq. 2 of Albrecht, Haber & Seidel 2002): with θ = 20/s and
# c = 1, a neighbour 80 ms away keeps e^(-1.6) ≈ 20 % of its weight, and seven
# 80 ms segments away e^(-11.2) ≈ 0.001 %: negligible, as the window requires.
DEFAULTS = {"alpha": 1.0, "theta_minus_per_s": 20.0, "theta_plus_per_s": 20.0, "c": 1.0, "t_off_ms": 0.0}
DOMINANCE_KEYS = list(DEFAULTS)

# ---------------------------------------------------------------------------
# Features: one row per phoneme of the model's inventory.
# ---------------------------------------------------------------------------

# Vowel quality. Closeness: 1 close .. 0 open; frontness: 1 front .. 0 back.
HEIGHT = {"close": 1.0, "near-close": 0.85, "close-mid": 0.65, "mid": 0.5,
          "open-mid": 0.35, "near-open": 0.15, "open": 0.0}
BACKNESS = {"front": 1.0, "near-front": 0.75, "central": 0.5, "near-back": 0.25, "back": 0.0}
ROUNDNESS = {"unrounded": 0.0, "slightly rounded": 0.35, "rounded": 0.65, "strongly rounded": 1.0}


def V(height, backness, rounding):
    return {"height": height, "backness": backness, "rounding": rounding}


# name: (example word, quality or (onset, offglide) for diphthongs, extra features)
VOWELS = {
    "iy": ("beat", V("close", "front", "unrounded"), {"tense": True}),
    "ih": ("bit", V("near-close", "near-front", "unrounded"), {}),
    "ey": ("bait", (V("close-mid", "front", "unrounded"), V("near-close", "near-front", "unrounded")), {}),
    "eh": ("bet", V("open-mid", "front", "unrounded"), {}),
    "ae": ("bat", V("near-open", "front", "unrounded"), {}),
    "aa": ("father", V("open", "back", "unrounded"), {}),
    "ao": ("bought", V("open-mid", "back", "rounded"), {}),
    "ow": ("boat", (V("close-mid", "back", "rounded"), V("near-close", "near-back", "rounded")), {}),
    "uh": ("book", V("near-close", "near-back", "rounded"), {}),
    "uw": ("boot", V("close", "back", "strongly rounded"), {"tense": True}),
    "ah": ("but", V("open-mid", "near-back", "unrounded"), {}),
    "ax": ("about", V("mid", "central", "unrounded"), {"reduced": True}),
    "er": ("bird", V("mid", "central", "slightly rounded"), {"rhotic": True}),
    "ay": ("bite", (V("open", "central", "unrounded"), V("near-close", "near-front", "unrounded")), {}),
    "aw": ("bout", (V("open", "central", "unrounded"), V("near-close", "near-back", "rounded")), {}),
    "oy": ("boy", (V("open-mid", "back", "rounded"), V("near-close", "near-front", "unrounded")), {}),
    # Vowels of the IPA chart that no English phoneme looks like (docs/languages.md): their own
    # phonemes, named ipa_ and their symbol, from the same features and rules as the English ones.
    "ipa_y": ("French lune, German über", V("close", "front", "rounded"), {"tense": True}),
    "ipa_ʏ": ("German Hütte", V("near-close", "near-front", "rounded"), {}),
    "ipa_ø": ("French peu, German schön", V("close-mid", "front", "rounded"), {}),
    "ipa_œ": ("French peur, German Hölle", V("open-mid", "front", "rounded"), {}),
    "ipa_ɶ": ("Danish (open front rounded)", V("open", "front", "rounded"), {}),
    "ipa_ɯ": ("Japanese u, Turkish ı", V("close", "back", "unrounded"), {"tense": True}),
    "ipa_ɤ": ("Vietnamese ơ, Mandarin e", V("close-mid", "back", "unrounded"), {}),
}

# name: (class, example, place, manner, voicing, extra)
CONSONANTS = {
    "pcl": ("closure", "the hold of /p/", "bilabial", "stop closure", "voiceless", {}),
    "bcl": ("closure", "the hold of /b/", "bilabial", "stop closure", "voiced", {}),
    "m": ("closure", "map", "bilabial", "nasal", "voiced", {}),
    "f": ("closure", "fan", "labiodental", "fricative", "voiceless", {}),
    "v": ("closure", "van", "labiodental", "fricative", "voiced", {}),
    "p": ("release", "pan", "bilabial", "stop release", "voiceless", {"closure": "pcl"}),
    "b": ("release", "ban", "bilabial", "stop release", "voiced", {"closure": "bcl"}),
    "t": ("consonant", "tan", "alveolar", "stop", "voiceless", {}),
    "d": ("consonant", "dan", "alveolar", "stop", "voiced", {}),
    "k": ("consonant", "can", "velar", "stop", "voiceless", {}),
    "g": ("consonant", "gap", "velar", "stop", "voiced", {}),
    "ch": ("consonant", "chin", "postalveolar", "affricate", "voiceless", {"sibilant": True}),
    "jh": ("consonant", "gin", "postalveolar", "affricate", "voiced", {"sibilant": True}),
    "th": ("consonant", "thin", "dental", "fricative", "voiceless", {}),
    "dh": ("consonant", "then", "dental", "fricative", "voiced", {}),
    "s": ("consonant", "sip", "alveolar", "fricative", "voiceless", {"sibilant": True}),
    "z": ("consonant", "zip", "alveolar", "fricative", "voiced", {"sibilant": True}),
    "sh": ("consonant", "ship", "postalveolar", "fricative", "voiceless", {"sibilant": True}),
    "zh": ("consonant", "measure", "postalveolar", "fricative", "voiced", {"sibilant": True}),
    "hh": ("consonant", "hat", "glottal", "fricative", "voiceless", {}),
    "n": ("consonant", "nap", "alveolar", "nasal", "voiced", {}),
    "ng": ("consonant", "sing", "velar", "nasal", "voiced", {}),
    "l": ("consonant", "lap", "alveolar", "lateral approximant", "voiced", {}),
    "r": ("consonant", "rap", "postalveolar", "approximant", "voiced", {"rhotic": True, "rounding": "rounded"}),
    "w": ("consonant", "wet", "labial-velar", "approximant", "voiced", {"rounding": "strongly rounded"}),
    "y": ("consonant", "yet", "palatal", "approximant", "voiced", {}),
    "dx": ("consonant", "butter (flap)", "alveolar", "flap", "voiced", {}),
    "q": ("consonant", "uh-oh (glottal stop)", "glottal", "stop", "voiceless", {}),
    # Consonants of the IPA chart that no English phoneme looks like (the others map to the English
    # phoneme with the same visible articulation: docs/languages.md).
    "ipa_ɸ": ("consonant", "Japanese fu", "bilabial", "fricative", "voiceless", {}),
    "ipa_β": ("consonant", "Spanish haba", "bilabial", "fricative", "voiced", {}),
    "ipa_ʙ": ("consonant", "bilabial trill (brr)", "bilabial", "trill", "voiced", {}),
    "ipa_r": ("consonant", "Spanish perro, Italian, Russian", "alveolar", "trill", "voiced", {}),
    "ipa_q": ("consonant", "Arabic qalb", "uvular", "stop", "voiceless", {}),
    "ipa_ʁ": ("consonant", "French rouge, German rot", "uvular", "fricative", "voiced", {}),
    "ipa_ħ": ("consonant", "Arabic ḥ", "pharyngeal", "fricative", "voiceless", {}),
    "ipa_ʕ": ("consonant", "Arabic ʿayn", "pharyngeal", "approximant", "voiced", {}),
}

# Labialisation (ʷ: kʷ, ɡʷ in MFA's English, Igbo, Caucasian and Salishan languages): a consonant with
# its lips rounded as a secondary articulation. Every consonant whose lips are otherwise free (not a
# bilabial, labiodental or labial-velar, nor already rounded like /r/) has a labialised partner
# `ipa_<name>ʷ`: its own features plus "labialised", which the rules below turn into rounded lips.
def labialised_name(name):
    return (name if name.startswith("ipa_") else "ipa_" + name) + "ʷ"


for _name, (_cls, _example, _place, _manner, _voicing, _extra) in list(CONSONANTS.items()):
    if _cls != "consonant" or _place in ("bilabial", "labiodental", "labial-velar") or "rounding" in _extra:
        continue
    if _name == "q":
        continue  # the glottal stop (ʔ): ipa_qʷ is the uvular's; ʔʷ falls back to ʔ
    CONSONANTS[labialised_name(_name)] = (_cls, _example + ", with rounded lips (ʷ)", _place, _manner, _voicing,
                                          dict(_extra, labialised=True, plain=_name))
LABIALISED = {CONSONANTS[n][5]["plain"]: n for n in CONSONANTS if CONSONANTS[n][5].get("labialised")}

INVENTORY = ["sil"] + [v for v in VOWELS if not v.startswith("ipa_")] + ["pcl", "bcl", "m", "f", "v", "p", "b"] + [
    "t", "d", "k", "g", "ch", "jh", "th", "dh", "s", "z", "sh", "zh", "hh", "n", "ng", "l", "r", "w",
    "y", "dx", "q"]
# The English inventory above, then the phonemes only other languages need.
ENGLISH_INVENTORY = list(INVENTORY)
INVENTORY += [name for name in list(VOWELS) + list(CONSONANTS) if name.startswith("ipa_")]
assert sorted(INVENTORY) == sorted(["sil"] + list(VOWELS) + list(CONSONANTS))

# ---------------------------------------------------------------------------
# Rules: features -> targets.
# ---------------------------------------------------------------------------


def set_group(targets, channels, value):
    for ch in channels:
        targets[ch] = value


def vowel_quality_targets(q, rhotic=False):
    """Targets of one vowel quality (a monophthong, or one end of a diphthong)."""
    close = HEIGHT[q["height"]]
    front = BACKNESS[q["backness"]]
    rnd = ROUNDNESS[q["rounding"]]
    openness = 1.0 - close
    t = {}
    # Open vowels open the jaw: from 0.15 for /i u/ to 0.85 for /a/.
    t["jaw_rotation"] = 0.15 + 0.7 * openness
    # Front vowels raise the tongue blade towards the palate; open vowels lower it with the jaw.
    t["tongue_raise"] = 0.4 * front * close - 0.45 * openness
    # Rounded vowels contract the orbicularis oris: the lips round and protrude.
    set_group(t, SPHINCTER, 0.85 * rnd)
    # Close rounded vowels also push the lower lip up a little with the mentalis.
    t["mentalis"] = 0.15 * rnd * close
    # Front unrounded vowels spread the lips (risorius) with a slight smile (zygomaticus), most for close /i/.
    spread = (1.0 - rnd) * front * (0.4 + 0.6 * close)
    set_group(t, SPREAD, 0.5 * spread)
    set_group(t, SMILE, 0.25 * spread)
    # Open vowels pull the lower lip down beyond what the jaw carries (depressor labii inferioris).
    lower = 0.5 * max(0.0, openness - 0.4) / 0.6 * (1.0 - 0.5 * rnd)
    set_group(t, LOWER_LIP_DOWN, lower)
    # Open front vowels bare the upper teeth a little (levator labii superioris).
    set_group(t, UPPER_LIP_RAISE, 0.2 * spread * openness)
    # Open back vowels draw the mouth corners down slightly (depressor anguli oris).
    set_group(t, CORNER_DOWN, 0.15 * openness * (1.0 - front))
    if rhotic:
        # r-coloured vowels bunch the tongue up and close the jaw a little.
        t["tongue_raise"] += 0.3
        t["jaw_rotation"] -= 0.1
    return t


def vowel_targets(name):
    _, quality, extra = VOWELS[name]
    rhotic = extra.get("rhotic", False)
    if isinstance(quality, tuple):
        # A diphthong has one target: 60 % onset, 40 % offglide (the model has one target per phoneme).
        onset = vowel_quality_targets(quality[0], rhotic)
        glide = vowel_quality_targets(quality[1], rhotic)
        return {ch: 0.6 * onset.get(ch, 0.0) + 0.4 * glide.get(ch, 0.0) for ch in set(onset) | set(glide)}
    return vowel_quality_targets(quality, rhotic)


# Jaw opening by place of articulation: the tighter and further forward the
# constriction, the closer the jaw (Keating et al. 1994; Lindblom 1983).
JAW_BY_PLACE = {
    # Bilabials and labiodentals: the jaw rises but does not close: the lips seal over an incisor
    # opening of a few millimetres (about 4 mm at 0.12 = 2.4 degrees; Keating et al. 1994 measure
    # 2-6 mm for /b/ between open vowels), and the lower lip reaches the upper teeth from there.
    # Both are explicit targets with closure dominance (see CLOSURE_ALPHA below).
    "bilabial": 0.12,
    "labiodental": 0.08,
    "dental": 0.14,        # a gap for the tongue tip between the teeth
    "alveolar": 0.12,
    "postalveolar": 0.1,
    "palatal": 0.1,
    "velar": 0.2,          # the tongue back does the work; the jaw is free
    "labial-velar": 0.12,
    "glottal": 0.25,       # no oral constriction: a neutral open mouth
    "uvular": 0.22,        # the tongue back against the uvula: the jaw is free, a little more open than a velar
    "pharyngeal": 0.3,     # the tongue root pulled back: no oral constriction, the jaw low
}


# The lower lip of a closure (bilabial or labiodental): the lower sphincter and the mentalis push it up
# against the upper lip or the upper teeth. Bilabials and labiodentals lie 0.03 either side of this.
LOWER_LIP_CLOSURE = {"orbicularis_oris_lower": 0.52, "mentalis": 0.58}


def consonant_targets(name):
    cls, _, place, manner, _, extra = CONSONANTS[name]
    sibilant = extra.get("sibilant", False)
    t = {}
    t["jaw_rotation"] = JAW_BY_PLACE[place]
    if sibilant:
        # Sibilants bring the teeth close together: the air jet hits the incisors.
        t["jaw_rotation"] -= 0.06
    if manner == "lateral approximant":
        # /l/ lowers the sides of the tongue; the jaw is a little more open than for /t/.
        t["jaw_rotation"] += 0.06
    if manner in ("flap", "approximant"):
        # Flaps and approximants make no tight constriction.
        t["jaw_rotation"] += 0.03

    if place == "bilabial" and cls == "closure":
        # Bilabials close the lips: the sphincter presses them together and the mentalis lifts the lower lip.
        # The lower lip's targets (lower sphincter, mentalis) are within 0.05 of the labiodentals', so that
        # where a bilabial and a labiodental closure meet ("of my", "come for") the shared key frame is
        # within 5 % of both.
        t["orbicularis_oris_upper"] = 0.35
        t["orbicularis_oris_lower"] = LOWER_LIP_CLOSURE["orbicularis_oris_lower"] - 0.03
        t["mentalis"] = LOWER_LIP_CLOSURE["mentalis"] + 0.03
    elif place == "bilabial" and cls == "consonant":
        # Bilabial fricatives and the trill (/ɸ β ʙ/) bring the lips nearly together without sealing
        # them: the sphincter narrows the opening, the mentalis lifts the lower lip less than for a
        # closure (ARKit mouthClose 0.3 · mentalis stays below jawOpen), and the trill leaves a little
        # more room for the lips to vibrate.
        t["orbicularis_oris_upper"] = 0.35
        t["orbicularis_oris_lower"] = 0.42
        t["mentalis"] = 0.25 if manner == "trill" else 0.3
        if manner == "trill":
            t["jaw_rotation"] += 0.02
    elif place == "bilabial" and cls == "release":
        # A /p b/ release: the lips just part, the jaw starts to drop.
        t["orbicularis_oris_upper"] = 0.2
        t["orbicularis_oris_lower"] = 0.25
        t["mentalis"] = 0.25
        t["jaw_rotation"] = 0.1
    elif place == "labiodental":
        # /f v/ tuck the lower lip under the upper teeth (orbicularis oris lower + mentalis)
        # and lift the upper lip a little to bare the upper teeth (levator labii superioris).
        t["orbicularis_oris_lower"] = LOWER_LIP_CLOSURE["orbicularis_oris_lower"] + 0.03
        t["mentalis"] = LOWER_LIP_CLOSURE["mentalis"] - 0.03
        t["orbicularis_oris_upper"] = 0.05
        set_group(t, UPPER_LIP_RAISE, 0.3)
    elif place == "dental":
        # Dentals push the tongue out between the teeth; the lower lip drops to show it.
        t["tongue_protrusion"] = 0.7
        t["tongue_raise"] = 0.25
        set_group(t, LOWER_LIP_DOWN, 0.25)
    elif place == "alveolar":
        # Alveolars raise the tongue tip to the alveolar ridge; the lips are neutral and slightly spread.
        t["tongue_raise"] = {"stop": 1.0, "nasal": 1.0, "flap": 0.85, "trill": 0.85, "lateral approximant": 0.9,
                             "fricative": 0.8}[manner]
        if manner == "trill":
            # The tongue tip vibrates against the ridge: a little more room than a flap.
            t["jaw_rotation"] += 0.05
        set_group(t, SPREAD, 0.3 if sibilant else 0.15)
        if sibilant:
            # /s z/ bare the teeth slightly.
            set_group(t, UPPER_LIP_RAISE, 0.1)
    elif place == "postalveolar":
        if extra.get("rhotic"):
            # English /r/ bunches or curls the tongue and rounds the lips.
            t["tongue_raise"] = 0.5
        else:
            # Postalveolars raise the tongue blade behind the ridge and protrude the lips (flared funnel);
            # affricates start with a stop, so their blade rises further.
            t["tongue_raise"] = 0.85 if manner == "affricate" else 0.7
            set_group(t, UPPER_LIP_RAISE, 0.2)
            set_group(t, LOWER_LIP_DOWN, 0.2)
            t["orbicularis_oris_upper"] = 0.5
            t["orbicularis_oris_lower"] = 0.45
            t["mentalis"] = 0.1
    elif place == "palatal":
        # /y/ raises the tongue body to the palate and spreads the lips like /i/.
        t["tongue_raise"] = 0.6
        set_group(t, SPREAD, 0.35)
        set_group(t, SMILE, 0.15)
    elif place == "velar":
        # Velars raise the tongue back: little of it shows, so only a small raise of the rigid tongue.
        t["tongue_raise"] = 0.3
    elif place == "labial-velar":
        # /w/ raises the tongue back like a velar.
        t["tongue_raise"] = 0.2
    elif place == "uvular":
        # Uvulars raise the tongue back further back than velars: less of it shows.
        t["tongue_raise"] = 0.2
    elif place == "pharyngeal":
        # Pharyngeals pull the tongue root back: the tongue body lowers; the lips are free.
        t["tongue_raise"] = -0.3
    elif place == "glottal":
        # /hh/ and the glottal stop have no oral target of their own (weak dominance below).
        pass
    if "rounding" in extra:
        # Rounded consonants (/w/, /r/) contract the orbicularis oris like rounded vowels.
        rnd = ROUNDNESS[extra["rounding"]]
        set_group(t, SPHINCTER, 0.9 * rnd)
        t["mentalis"] = 0.25 * rnd
    if extra.get("labialised"):
        # Labialised consonants (kʷ) round the lips as a rounded consonant does (/r/: "rounded"), on top
        # of their own place; rounded lips do not spread.
        rnd = ROUNDNESS["rounded"]
        for ch in SPHINCTER:
            t[ch] = max(t.get(ch, 0.0), 0.9 * rnd)
        t["mentalis"] = max(t.get("mentalis", 0.0), 0.25 * rnd)
        for ch in SPREAD + SMILE:
            t.pop(ch, None)
    return t


def targets_of(name):
    if name == "sil":
        return {}  # silence is the face at rest
    return vowel_targets(name) if name in VOWELS else consonant_targets(name)


# ---------------------------------------------------------------------------
# Rules: features -> dominance (α, θ−, θ+, c, t_off), per channel.
# ---------------------------------------------------------------------------


# Closure dominance (paper Section 3.2: "by assigning a high magnitude to the dominance function of
# the closure phoneme, the lips come sufficiently close to their targets"). The engine gives a closure's
# dominance its peak over the whole hold (Eq. 3' in docs/coarticulation.md), so at both key frames the
# closure weighs α. With α = 100 against the α ≤ 5 of any other phoneme, the closing channels are within
# 5 % of their targets there whatever the neighbours. Outside the hold the dominance falls as a Gaussian
# (c = 2): it equals a vowel's (α = 1) at `reach` before the hold and at `reach` · RELEASE_SHARE after it
# (the lips open faster than they close), and is negligible 2 · reach away, so the neighbouring vowels
# still open.
CLOSURE_ALPHA = 100.0
# One reach for lips and jaw: the channels then share one dominance shape, so the evaluator takes one
# exponential for them (an evaluator cost per shape, docs/performance.md).
CLOSURE_REACH_MS = 30.0
RELEASE_SHARE = 0.7


def closure_dominance(put, channels, reach_ms):
    reach_s = reach_ms / 1000.0
    put(channels, alpha=CLOSURE_ALPHA, c=2.0,
        theta_plus_per_s=math.log(CLOSURE_ALPHA) / reach_s ** 2,
        theta_minus_per_s=math.log(CLOSURE_ALPHA) / (RELEASE_SHARE * reach_s) ** 2)


def dominance_of(name):
    """Returns {channel: {alpha, theta_minus_per_s, theta_plus_per_s, c, t_off_ms}}."""
    dom = {ch: dict(DEFAULTS) for ch in CHANNEL_NAMES}

    def put(channels, **values):
        for ch in channels:
            dom[ch].update(values)

    def theta(channels, value):
        put(channels, theta_minus_per_s=value, theta_plus_per_s=value)

    if name == "sil":
        # Silence is at rest with low-moderate dominance and a slow rate, so the mouth already moves
        # towards the next phoneme during a pause (paper, Fig. 7) while a long pause still reaches rest.
        put(CHANNEL_NAMES, alpha=0.5)
        theta(CHANNEL_NAMES, 12.0)
        return dom

    if name in VOWELS:
        _, quality, extra = VOWELS[name]
        # Vowels have full dominance over every channel with a moderately slow rate.
        theta(CHANNEL_NAMES, 18.0)
        if isinstance(quality, tuple):
            # Diphthongs are long gestures: a slower rate.
            theta(CHANNEL_NAMES, 15.0)
        rounding = max(ROUNDNESS[q["rounding"]] for q in (quality if isinstance(quality, tuple) else (quality,)))
        if rounding > 0.0:
            # Lip rounding is anticipated ("coin" vs "cow"): on the rounding channels a rounded vowel is
            # more dominant, peaks 25 ms before its centre and rises over a longer time (θ+ 12/s).
            put(ROUNDING, alpha=1.0 + rounding, theta_plus_per_s=12.0, t_off_ms=25.0)
        if extra.get("reduced"):
            # Schwa is weak: it takes the shape of its neighbours.
            put(CHANNEL_NAMES, alpha=0.3)
            theta(CHANNEL_NAMES, 25.0)
        return dom

    cls, _, place, manner, _, extra = CONSONANTS[name]
    # Consonants: the articulators that make the constriction dominate; the others are free
    # (α 0.5) and take the shape of the neighbouring vowels (Pelachaud et al. 1996).
    theta(CHANNEL_NAMES, 22.0)
    put(CHANNEL_NAMES, alpha=0.5)
    if place == "bilabial" and cls == "closure":
        # Bilabials close the lips: closure dominance (see closure_dominance) on the lip-seal channels and
        # the jaw, so that the lips are closed at both key frames of the hold, and low dominance on the
        # tongue.
        closure_dominance(put, LIP_SEAL + JAW, CLOSURE_REACH_MS)
        put(SMILE + SPREAD + UPPER_LIP_RAISE + CORNER_DOWN + LOWER_LIP_DOWN, alpha=1.0)
        put(TONGUE, alpha=0.1)
    elif place == "bilabial" and cls == "consonant":
        # /ɸ β ʙ/: the lips dominate as strongly as /w/ rounds them and the jaw as a sibilant's (the
        # most any non-closure has), but with no closure dominance: they come near each other
        # whatever the neighbours, and need not seal.
        put(LIP_SEAL, alpha=5.0)
        put(JAW, alpha=3.0)
        put(TONGUE, alpha=0.1)
    elif place == "bilabial" and cls == "release":
        # /p b/ releases: the lips just part; the engine puts the peak at the start of the release.
        put(LIP_SEAL, alpha=3.0)
        theta(LIP_SEAL, 40.0)
        put(JAW, alpha=1.5)
        put(TONGUE, alpha=0.1)
    elif place == "labiodental":
        # /f v/: the lower lip must touch the upper teeth, handled like a bilabial closure (paper 3.2):
        # closure dominance on the lower lip and the jaw; the raised upper lip (bared teeth) is strong
        # but shaped by Eq. 2 alone.
        closure_dominance(put, ["orbicularis_oris_lower", "mentalis"] + JAW, CLOSURE_REACH_MS)
        put(UPPER_LIP_RAISE, alpha=6.0)
        theta(UPPER_LIP_RAISE, 35.0)
        put(["orbicularis_oris_upper"], alpha=1.0)
        put(TONGUE, alpha=0.1)
    elif place == "dental":
        # Dentals: the visible tongue tip dominates.
        put(["tongue_protrusion"], alpha=5.0)
        put(["tongue_raise"] + JAW, alpha=2.0)
        put(LOWER_LIP_DOWN, alpha=1.5)
    elif place == "alveolar":
        # Alveolars: the tongue tip dominates; sibilants also need the teeth close together.
        put(["tongue_raise"], alpha=5.0 if extra.get("sibilant") else 4.0)
        put(["tongue_protrusion"], alpha=2.0)
        put(JAW, alpha=3.0 if extra.get("sibilant") else 1.5)
        if manner == "flap":
            # A flap is a brief tap: weaker and faster.
            put(["tongue_raise"], alpha=2.0)
            theta(CHANNEL_NAMES, 30.0)
    elif place == "postalveolar":
        # Postalveolars: tongue blade and lip protrusion (for /r/: lip rounding) both matter.
        put(["tongue_raise"], alpha=3.0 if not extra.get("rhotic") else 2.0)
        put(["tongue_protrusion"], alpha=1.0)
        put(SPHINCTER + CHIN, alpha=2.5 if not extra.get("rhotic") else 2.0)
        put(JAW, alpha=2.0 if extra.get("sibilant") else 1.0)
    elif place == "palatal":
        put(["tongue_raise"], alpha=2.0)
        put(SPREAD + SMILE, alpha=1.0)
    elif place == "velar":
        # Velars raise the tongue back less visibly: little dominance anywhere, so the lips keep the
        # shape of the neighbours (the rounded /k/ of "coin").
        put(["tongue_raise"] + JAW, alpha=1.0)
        put(LIPS, alpha=0.3)
    elif place == "uvular":
        # Uvulars: like velars, little dominance; the lips keep the neighbours' shape.
        put(["tongue_raise"] + JAW, alpha=1.0)
        put(LIPS, alpha=0.3)
    elif place == "pharyngeal":
        # Pharyngeals: weak like /hh/, with the lowered tongue and open jaw a little stronger.
        put(CHANNEL_NAMES, alpha=0.2)
        put(["tongue_raise"] + JAW, alpha=0.8)
    elif place == "labial-velar":
        # /w/ is strongly rounded: lip rounding dominates, anticipated like a rounded vowel.
        put(ROUNDING, alpha=5.0, theta_plus_per_s=15.0, t_off_ms=15.0)
        put(JAW, alpha=1.0)
        put(TONGUE, alpha=0.3)
    elif place == "glottal":
        # /hh/ and the glottal stop are weak: they take the shape of their neighbours.
        put(CHANNEL_NAMES, alpha=0.2)
    if extra.get("labialised"):
        # Labialisation: the rounding channels dominate as a rounded vowel's do (α 1 + rounding), with
        # the vowel's slow, anticipated rise, and the spreading channels give way to them.
        put(ROUNDING, alpha=1.0 + ROUNDNESS["rounded"], theta_plus_per_s=12.0, theta_minus_per_s=22.0)
        put(SPREAD + SMILE, alpha=min(dom[SPREAD[0]]["alpha"], 0.5))
    return dom


# ---------------------------------------------------------------------------
# ARKit retargeting: blendshape = clamp(Σ weight · channel, 0, 1).
# ---------------------------------------------------------------------------

ARKIT_NAMES = [
    "eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft",
    "eyeSquintLeft", "eyeWideLeft", "eyeBlinkRight", "eyeLookDownRight", "eyeLookInRight",
    "eyeLookOutRight", "eyeLookUpRight", "eyeSquintRight", "eyeWideRight", "jawForward", "jawLeft",
    "jawRight", "jawOpen", "mouthClose", "mouthFunnel", "mouthPucker", "mouthLeft", "mouthRight",
    "mouthSmileLeft", "mouthSmileRight", "mouthFrownLeft", "mouthFrownRight", "mouthDimpleLeft",
    "mouthDimpleRight", "mouthStretchLeft", "mouthStretchRight", "mouthRollLower", "mouthRollUpper",
    "mouthShrugLower", "mouthShrugUpper", "mouthPressLeft", "mouthPressRight", "mouthLowerDownLeft",
    "mouthLowerDownRight", "mouthUpperUpLeft", "mouthUpperUpRight", "browDownLeft", "browDownRight",
    "browInnerUp", "browOuterUpLeft", "browOuterUpRight", "cheekPuff", "cheekSquintLeft",
    "cheekSquintRight", "noseSneerLeft", "noseSneerRight", "tongueOut",
]

OOU, OOL, MENT = "orbicularis_oris_upper", "orbicularis_oris_lower", "mentalis"


def sided(shape_left, shape_right, channel_left, channel_right, weight, note, extra_left=None, extra_right=None):
    left = {channel_left: weight}
    right = {channel_right: weight}
    left.update(extra_left or {})
    right.update(extra_right or {})
    return [(shape_left, left, note), (shape_right, right, note)]


# The mentalis is what tells a closure (or /f v/) from rounding: it is high for
# closures and the lip tuck, low for rounded vowels. Funnel and pucker subtract it.
ARKIT_ROWS = [
    ("jawOpen", {"jaw_rotation": 1.0}, "the jaw channel is the ARKit jaw opening"),
    ("mouthClose", {MENT: 0.3},
     "lips held together while the jaw is open: the mentalis lifts the lower lip for closures"),
    ("mouthFunnel", {OOU: 0.5, OOL: 0.5, MENT: -0.9, "depressor_labii_inferioris_left": 0.1,
                     "depressor_labii_inferioris_right": 0.1},
     "open rounding (/sh/, /ow/): the sphincter with the lower lip flared; the mentalis of a closure cancels it"),
    ("mouthPucker", {OOU: 0.6, OOL: 0.6, MENT: -0.8, "depressor_labii_inferioris_left": -0.15,
                     "depressor_labii_inferioris_right": -0.15},
     "tight protruded rounding (/uw/, /w/): the sphincter, less when the lower lip is flared or pressed up"),
]
ARKIT_ROWS += sided("mouthSmileLeft", "mouthSmileRight", "zygomaticus_major_left", "zygomaticus_major_right",
                    1.0, "the zygomaticus major pulls the corner up and back")
ARKIT_ROWS += sided("mouthFrownLeft", "mouthFrownRight", "depressor_anguli_oris_left",
                    "depressor_anguli_oris_right", 1.0, "the depressor anguli oris pulls the corner down")
ARKIT_ROWS += sided("mouthDimpleLeft", "mouthDimpleRight", "risorius_left", "risorius_right", 0.2,
                    "lip spreading also draws the corner back a little")
ARKIT_ROWS += sided("mouthStretchLeft", "mouthStretchRight", "risorius_left", "risorius_right", 1.0,
                    "the risorius stretches the corner sideways")
ARKIT_ROWS += [
    ("mouthRollLower", {OOL: 0.8, OOU: -0.7, MENT: 0.3},
     "the lower lip drawn in under the upper teeth (/f v/): lower sphincter without the upper, with the mentalis"),
    ("mouthRollUpper", {MENT: 0.3, "levator_labii_superioris_left": -0.3, "levator_labii_superioris_right": -0.3},
     "closures roll the upper lip in slightly; not when the upper lip is raised (/f v/)"),
    ("mouthShrugLower", {MENT: 0.7}, "the mentalis raises the chin and pushes the lower lip up"),
    ("mouthShrugUpper", {MENT: 0.3}, "the pushed-up lower lip lifts the upper lip with it"),
]
ARKIT_ROWS += sided("mouthPressLeft", "mouthPressRight", MENT, MENT, 0.6,
                    "closed lips pressed together by the mentalis; less when the upper lip is raised (/f v/)",
                    {"levator_labii_superioris_left": -0.5}, {"levator_labii_superioris_right": -0.5})
ARKIT_ROWS += sided("mouthLowerDownLeft", "mouthLowerDownRight", "depressor_labii_inferioris_left",
                    "depressor_labii_inferioris_right", 1.0, "the depressor labii inferioris pulls the lower lip down")
ARKIT_ROWS += sided("mouthUpperUpLeft", "mouthUpperUpRight", "levator_labii_superioris_left",
                    "levator_labii_superioris_right", 1.0, "the levator labii superioris raises the upper lip")
ARKIT_ROWS += sided("cheekSquintLeft", "cheekSquintRight", "zygomaticus_major_left", "zygomaticus_major_right",
                    0.3, "the zygomaticus major lifts the cheek")
ARKIT_ROWS += sided("noseSneerLeft", "noseSneerRight", "levator_labii_superioris_left",
                    "levator_labii_superioris_right", 0.2, "the levator labii superioris wrinkles the nose side a little")
ARKIT_ROWS += [("tongueOut", {"tongue_protrusion": 1.0}, "tongue tip out between the teeth (/th dh/)")]

# ---------------------------------------------------------------------------
# Notes: one line per phoneme, why it looks like this.
# ---------------------------------------------------------------------------

NOTES = {
    "sil": "face at rest; low-moderate dominance so the mouth anticipates the next phoneme during a pause",
    "iy": "close front unrounded: jaw nearly closed, lips spread, tongue blade high",
    "ih": "near-close front: like /iy/ but a little more open and less spread",
    "ey": "diphthong e -> I: half-open jaw, spread lips",
    "eh": "open-mid front: jaw half open, lips slightly spread",
    "ae": "near-open front: jaw open, lips spread, lower lip down",
    "aa": "open back: the widest jaw opening, tongue low",
    "ao": "open-mid back rounded: open jaw with rounded lips",
    "ow": "diphthong o -> U: rounded lips, closing jaw",
    "uh": "near-close back rounded: lips rounded, jaw nearly closed",
    "uw": "close back strongly rounded: lips rounded and protruded",
    "ah": "open-mid back unrounded: jaw half open, neutral lips",
    "ax": "schwa: weak, takes the shape of its neighbours",
    "er": "r-coloured mid vowel: slight rounding, tongue bunched up",
    "ay": "diphthong a -> I: open jaw moving towards spread",
    "aw": "diphthong a -> U: open jaw moving towards rounding",
    "oy": "diphthong O -> I: rounded lips moving towards spread",
    "pcl": "bilabial stop hold: lips pressed together over a slightly open jaw, closure dominance on lips and jaw",
    "bcl": "bilabial stop hold: lips pressed together over a slightly open jaw, closure dominance on lips and jaw",
    "m": "bilabial nasal: lips closed like the stop closure (no release needed)",
    "f": "labiodental: lower lip tucked under the upper teeth, upper teeth bared; closure dominance on lower lip and jaw",
    "v": "labiodental: lower lip tucked under the upper teeth, upper teeth bared; closure dominance on lower lip and jaw",
    "p": "release of /p/: lips just parting; the engine peaks it at the start of the segment",
    "b": "release of /b/: lips just parting; the engine peaks it at the start of the segment",
    "t": "alveolar stop: tongue tip on the ridge, lips free",
    "d": "alveolar stop: tongue tip on the ridge, lips free",
    "k": "velar stop: tongue back raised, barely visible; lips take the neighbours' shape",
    "g": "velar stop: tongue back raised, barely visible; lips take the neighbours' shape",
    "ch": "postalveolar affricate: teeth close, lips protruded and flared",
    "jh": "postalveolar affricate: teeth close, lips protruded and flared",
    "th": "dental fricative: tongue tip out between the teeth",
    "dh": "dental fricative: tongue tip out between the teeth",
    "s": "alveolar sibilant: teeth close together, lips slightly spread",
    "z": "alveolar sibilant: teeth close together, lips slightly spread",
    "sh": "postalveolar sibilant: teeth close, lips protruded and flared",
    "zh": "postalveolar sibilant: teeth close, lips protruded and flared",
    "hh": "glottal: no oral target, takes the shape of the following vowel",
    "n": "alveolar nasal: tongue tip on the ridge",
    "ng": "velar nasal: tongue back raised, barely visible",
    "l": "alveolar lateral: tongue tip on the ridge, jaw a little open",
    "r": "English r: tongue bunched, lips rounded",
    "w": "labial-velar glide: strongly rounded, protruded lips, anticipated",
    "y": "palatal glide: tongue body high, lips spread like /iy/",
    "dx": "alveolar flap: a brief, weak tap of the tongue tip",
    "q": "glottal stop: no oral target, takes the shape of its neighbours",
    "ipa_y": "close front rounded: the jaw and tongue of /iy/ with rounded, protruded lips",
    "ipa_ʏ": "near-close front rounded: the jaw and tongue of /ih/ with rounded lips",
    "ipa_ø": "close-mid front rounded: a half-closed jaw, tongue forward, rounded lips",
    "ipa_œ": "open-mid front rounded: the jaw of /eh/ with rounded lips",
    "ipa_ɶ": "open front rounded: the jaw of /ae/ with rounded lips",
    "ipa_ɯ": "close back unrounded: the jaw of /uw/, the lips neither rounded nor spread",
    "ipa_ɤ": "close-mid back unrounded: the jaw of /ow/, the lips neither rounded nor spread",
    "ipa_ɸ": "bilabial fricative: lips nearly together, not sealed; strong but no closure dominance",
    "ipa_β": "bilabial fricative: lips nearly together, not sealed; strong but no closure dominance",
    "ipa_ʙ": "bilabial trill: lips nearly together and loose enough to vibrate; not sealed",
    "ipa_r": "alveolar trill: the tongue tip vibrates at the ridge, lips free (English r is rounded: not this one)",
    "ipa_q": "uvular stop: tongue back raised far back, barely visible; lips take the neighbours' shape",
    "ipa_ʁ": "uvular r (fricative or approximant): the tongue back as for q; lips take the neighbours' shape",
    "ipa_ħ": "pharyngeal fricative: tongue root back, jaw a little open; weak like /hh/",
    "ipa_ʕ": "pharyngeal approximant: tongue root back, jaw a little open; weak like /hh/",
}
for _plain, _labialised in LABIALISED.items():
    NOTES[_labialised] = NOTES[_plain] + "; labialised: the lips rounded as for /r/, anticipated"


def features_of(name):
    if name == "sil":
        return {"type": "silence"}
    if name in VOWELS:
        example, quality, extra = VOWELS[name]
        f = {"example": example}
        if isinstance(quality, tuple):
            f["diphthong"] = True
            f["onset"] = dict(quality[0])
            f["offglide"] = dict(quality[1])
        else:
            f.update(quality)
        for key in ("tense", "reduced", "rhotic"):
            if extra.get(key):
                f[key] = True
        return f
    _, example, place, manner, voicing, extra = CONSONANTS[name]
    f = {"example": example, "place": place, "manner": manner, "voicing": voicing}
    for key in ("sibilant", "rhotic", "rounding", "labialised"):
        if key in extra:
            f[key] = extra[key]
    return f


# ---------------------------------------------------------------------------
# Assembling the model JSON.
# ---------------------------------------------------------------------------


def num(x):
    """Rounds to at most 4 decimals; never writes -0.0."""
    r = round(float(x), 4)
    return 0.0 if r == 0 else r


def compress_dominance(per_channel):
    """Splits per-channel parameters into a phoneme-wide "dominance" (differences from the
    defaults shared by most channels) and "channel_dominance" overrides on top of it."""
    def diff(params, base):
        return {k: num(params[k]) for k in DOMINANCE_KEYS if num(params[k]) != num(base[k])}

    # The most common parameter set becomes the phoneme-wide one (ties: first in channel order).
    counts = {}
    order = []
    for ch in CHANNEL_NAMES:
        key = tuple(num(per_channel[ch][k]) for k in DOMINANCE_KEYS)
        if key not in counts:
            order.append(key)
            counts[key] = 0
        counts[key] += 1
    common = max(order, key=lambda k: counts[k])
    phoneme_wide = dict(zip(DOMINANCE_KEYS, common))
    dominance = diff(phoneme_wide, DEFAULTS)
    channel = {}
    for ch in CHANNEL_NAMES:
        d = diff(per_channel[ch], phoneme_wide)
        if d:
            channel[ch] = d
    return dominance, channel


def phoneme_entry(name):
    cls = "silence" if name == "sil" else ("vowel" if name in VOWELS else CONSONANTS[name][0])
    entry = {"class": cls}
    if cls == "release":
        entry["closure"] = CONSONANTS[name][5]["closure"]
    entry["features"] = features_of(name)
    entry["note"] = NOTES[name]
    raw = targets_of(name)
    targets = {}
    for ch in CHANNEL_NAMES:
        if ch in raw:
            lo, hi = RANGE[ch]
            value = num(min(hi, max(lo, raw[ch])))
            if value != num(REST[ch]):
                targets[ch] = value
    entry["targets"] = targets
    dominance, channel = compress_dominance(dominance_of(name))
    if dominance:
        entry["dominance"] = dominance
    if channel:
        entry["channel_dominance"] = channel
    return entry


def build_model():
    model = {
        "format": "lipsync-articulation-model",
        "version": 1,
        "name": "default",
        "description": (
            "lipsyncd's default articulation model: targets and Cohen-Massaro dominance functions for "
            "16 muscle, jaw and tongue channels, derived from phonetic features by "
            "tools/make_default_model.py (do not edit by hand; see docs/model.md)."),
        "channels": [
            {"name": n, "kind": k, "min": num(lo), "max": num(hi), "rest": num(rest), "description": d}
            for (n, k, lo, hi, rest, d) in CHANNELS
        ],
        "dominance_defaults": {k: num(v) for k, v in DEFAULTS.items()},
        "phonemes": {name: phoneme_entry(name) for name in INVENTORY},
        "arkit": {},
    }
    rows = {}
    for shape, weights, note in ARKIT_ROWS:
        assert shape in ARKIT_NAMES and shape not in rows, shape
        assert all(ch in CHANNEL_NAMES for ch in weights), shape
        rows[shape] = {"weights": {ch: num(weights[ch]) for ch in CHANNEL_NAMES if ch in weights}, "note": note}
    model["arkit"] = {shape: rows[shape] for shape in ARKIT_NAMES if shape in rows}
    return model


# ---------------------------------------------------------------------------
# Phone sets: input label -> model phoneme. Each table lists (label, phoneme,
# note); a note explains a mapping that is not a one-to-one renaming.
# ---------------------------------------------------------------------------

ARPABET_VOWELS = [
    ("AA", "aa", ""), ("AE", "ae", ""), ("AH", "ah", ""), ("AO", "ao", ""), ("AW", "aw", ""),
    ("AY", "ay", ""), ("EH", "eh", ""), ("ER", "er", ""), ("EY", "ey", ""), ("IH", "ih", ""),
    ("IY", "iy", ""), ("OW", "ow", ""), ("OY", "oy", ""), ("UH", "uh", ""), ("UW", "uw", ""),
    ("AX", "ax", "extended ARPAbet schwa"), ("AXR", "er", "r-coloured schwa"),
    ("IX", "ih", "extended ARPAbet reduced i"), ("UX", "uw", "extended ARPAbet fronted u"),
]
ARPABET_CONSONANTS = [
    ("B", "b", "the segment builder splits it into closure and release"), ("CH", "ch", ""), ("D", "d", ""),
    ("DH", "dh", ""), ("F", "f", ""), ("G", "g", ""), ("HH", "hh", ""), ("JH", "jh", ""), ("K", "k", ""),
    ("L", "l", ""), ("M", "m", ""), ("N", "n", ""), ("NG", "ng", ""),
    ("P", "p", "the segment builder splits it into closure and release"), ("R", "r", ""), ("S", "s", ""),
    ("SH", "sh", ""), ("T", "t", ""), ("TH", "th", ""), ("V", "v", ""), ("W", "w", ""), ("Y", "y", ""),
    ("Z", "z", ""), ("ZH", "zh", ""),
    ("DX", "dx", "flap"), ("EL", "l", "syllabic l"), ("EM", "m", "syllabic m"), ("EN", "n", "syllabic n"),
    ("ENG", "ng", "syllabic ng"), ("NX", "n", "nasal flap"), ("Q", "q", "glottal stop"),
    ("WH", "w", "voiceless w"),
    ("SIL", "sil", "silence (MFA, Sphinx)"), ("SP", "sil", "short pause (MFA)"),
    ("SPN", "sil", "spoken noise (MFA): no phonetic content"),
    ("+NSN+", "sil", "noise (pocketsphinx)"), ("+SPN+", "sil", "spoken noise (pocketsphinx)"),
]


def arpabet_phones():
    rows = []
    for label, target, note in ARPABET_VOWELS:
        rows.append((label, target, note))
        for stress in "012":
            if label == "AH" and stress == "0":
                # CMUdict writes schwa as unstressed AH.
                rows.append(("AH0", "ax", "CMUdict's schwa is unstressed AH: weak like ax"))
            else:
                rows.append((label + stress, target, ""))
    return rows + ARPABET_CONSONANTS


RADIO = [
    ("aa", "aa", ""), ("ae", "ae", ""), ("ah", "ah", ""), ("ao", "ao", ""), ("aw", "aw", ""),
    ("ax", "ax", ""), ("axr", "er", "r-coloured schwa"), ("ay", "ay", ""), ("b", "b", ""),
    ("ch", "ch", ""), ("d", "d", ""), ("dh", "dh", ""), ("dx", "dx", "flap"), ("eh", "eh", ""),
    ("el", "l", "syllabic l"), ("em", "m", "syllabic m"), ("en", "n", "syllabic n"), ("er", "er", ""),
    ("ey", "ey", ""), ("f", "f", ""), ("g", "g", ""), ("hh", "hh", ""), ("hv", "hh", "voiced h"),
    ("ih", "ih", ""), ("iy", "iy", ""), ("jh", "jh", ""), ("k", "k", ""), ("l", "l", ""), ("m", "m", ""),
    ("n", "n", ""), ("ng", "ng", ""), ("nx", "n", "nasal flap"), ("ow", "ow", ""), ("oy", "oy", ""),
    ("p", "p", ""), ("r", "r", ""), ("s", "s", ""), ("sh", "sh", ""), ("t", "t", ""), ("th", "th", ""),
    ("uh", "uh", ""), ("uw", "uw", ""), ("v", "v", ""), ("w", "w", ""), ("y", "y", ""), ("z", "z", ""),
    ("zh", "zh", ""),
    ("pau", "sil", "pause"), ("h#", "sil", "utterance-edge silence"), ("brth", "sil", "breath: mouth at rest"),
]

TIMIT = [
    ("aa", "aa", ""), ("ae", "ae", ""), ("ah", "ah", ""), ("ao", "ao", ""), ("aw", "aw", ""),
    ("ax", "ax", ""), ("ax-h", "ax", "devoiced schwa"), ("axr", "er", "r-coloured schwa"),
    ("ay", "ay", ""), ("b", "b", "release; follows bcl"), ("bcl", "bcl", "bilabial closure"),
    ("ch", "ch", ""), ("d", "d", ""), ("dcl", "d", "tongue closure inside the mouth: modelled as the stop"),
    ("dh", "dh", ""), ("dx", "dx", "flap"), ("eh", "eh", ""), ("el", "l", "syllabic l"),
    ("em", "m", "syllabic m"), ("en", "n", "syllabic n"), ("eng", "ng", "syllabic ng"),
    ("epi", "sil", "epenthetic silence"), ("er", "er", ""), ("ey", "ey", ""), ("f", "f", ""),
    ("g", "g", ""), ("gcl", "g", "tongue closure inside the mouth: modelled as the stop"),
    ("h#", "sil", "utterance-edge silence"), ("hh", "hh", ""), ("hv", "hh", "voiced h"),
    ("ih", "ih", ""), ("ix", "ih", "reduced i"), ("iy", "iy", ""), ("jh", "jh", ""), ("k", "k", ""),
    ("kcl", "k", "tongue closure inside the mouth: modelled as the stop"), ("l", "l", ""),
    ("m", "m", ""), ("n", "n", ""), ("ng", "ng", ""), ("nx", "n", "nasal flap"), ("ow", "ow", ""),
    ("oy", "oy", ""), ("p", "p", "release; follows pcl"), ("pau", "sil", "pause"),
    ("pcl", "pcl", "bilabial closure"), ("q", "q", "glottal stop"), ("r", "r", ""), ("s", "s", ""),
    ("sh", "sh", ""), ("t", "t", ""), ("tcl", "t", "tongue closure inside the mouth: modelled as the stop"),
    ("th", "th", ""), ("uh", "uh", ""), ("uw", "uw", ""), ("ux", "uw", "fronted u"), ("v", "v", ""),
    ("w", "w", ""), ("y", "y", ""), ("z", "z", ""), ("zh", "zh", ""),
]
assert len(TIMIT) == 61

# IPA: what espeak-ng prints (--ipa, and its phoneme events with
# espeakINITIALIZE_PHONEME_IPA) for its English voices, and what the Montreal
# Forced Aligner's english_mfa / english_us_mfa / english_uk_mfa models use.
# Length (ː) is kept: aː (PALM/START in MFA's UK dictionary) differs from a (TRAP).
IPA_VOWELS = [
    ("i", "iy", ""), ("ɪ", "ih", ""), ("ᵻ", "ih", "espeak's reduced i (roses)"), ("ɨ", "ih", ""),
    ("e", "ey", "close-mid front: the quality of ey (MFA's FACE monophthong)"), ("ɛ", "eh", ""),
    ("æ", "ae", ""), ("a", "ae", "open front: TRAP in British transcriptions"),
    ("ɐ", "ah", "near-open central: STRUT in MFA's British English, reduced a in espeak"),
    ("ə", "ax", ""), ("ɘ", "ax", ""), ("ɚ", "er", ""), ("ɝ", "er", ""), ("ɜ", "er", ""), ("ɞ", "er", ""),
    ("ʌ", "ah", ""), ("ɑ", "aa", ""), ("ɒ", "aa", "rounded LOT: open back, like aa"), ("ɔ", "ao", ""),
    ("o", "ow", "close-mid back rounded: the quality of ow"), ("ʊ", "uh", ""), ("ɵ", "uh", ""),
    ("u", "uw", ""), ("ʉ", "uw", "fronted u (MFA, espeak en-gb-scotland)"),
    ("y", "ipa_y", "close front rounded"), ("ʏ", "ipa_ʏ", "near-close front rounded"),
    ("ø", "ipa_ø", "close-mid front rounded"), ("œ", "ipa_œ", "open-mid front rounded"),
    ("ɶ", "ipa_ɶ", "open front rounded"), ("ɯ", "ipa_ɯ", "close back unrounded"),
    ("ɤ", "ipa_ɤ", "close-mid back unrounded"),
]
IPA_LONG_OVERRIDES = {"aː": ("aa", "long open a: PALM/START (MFA British English)"),
                      "ɐː": ("aa", "long open a: START (Australian)")}
IPA_OTHER_VOWELS = [
    # diphthongs -> the model's single diphthong phonemes
    ("aɪ", "ay", ""), ("aj", "ay", "MFA spelling"), ("ɑɪ", "ay", ""), ("ʌɪ", "ay", ""), ("ɐɪ", "ay", ""),
    ("eɪ", "ey", ""), ("ej", "ey", "MFA spelling"), ("ei", "ey", ""), ("ɛɪ", "ey", ""),
    ("əɪ", "ey", "espeak en-us-nyc NURSE vowel"),
    ("ɔɪ", "oy", ""), ("oɪ", "oy", ""), ("ɔj", "oy", "MFA spelling"),
    ("aʊ", "aw", ""), ("aw", "aw", "MFA spelling"), ("æʊ", "aw", ""), ("ɑʊ", "aw", ""), ("ɐʊ", "aw", ""),
    ("ʌʉ", "aw", "espeak en-gb-scotland MOUTH"),
    ("oʊ", "ow", ""), ("əʊ", "ow", ""), ("əw", "ow", "MFA spelling"), ("ow", "ow", "MFA spelling"),
    ("ʌʊ", "ow", ""), ("ɔʊ", "ow", ""), ("əu", "uw", "espeak's diphthongised GOOSE"),
    # centring diphthongs -> the nearest vowel
    ("ɪə", "ih", "centring diphthong: the nearest vowel"), ("iə", "ih", "centring diphthong: the nearest vowel"),
    ("eə", "eh", "centring diphthong: the nearest vowel"), ("ɛə", "eh", "centring diphthong: the nearest vowel"),
    ("ʊə", "uh", "centring diphthong: the nearest vowel"), ("uə", "uh", "centring diphthong: the nearest vowel"),
    ("ɔə", "ao", "centring diphthong: the nearest vowel"), ("oə", "ao", "centring diphthong: the nearest vowel"),
    ("ɑə", "aa", "centring diphthong: the nearest vowel"),
    # triphthongs (one espeak phoneme)
    ("aɪə", "ay", "triphthong: its diphthong"), ("aɪɚ", "ay", "triphthong: its diphthong"),
    ("aʊə", "aw", "triphthong: its diphthong"), ("aʊɚ", "aw", "triphthong: its diphthong"),
    # r-coloured vowels (one espeak phoneme): the vowel; the r colouring is not modelled
    ("ɑɹ", "aa", "r-coloured vowel: its vowel"), ("ɑːɹ", "aa", "r-coloured vowel: its vowel"),
    ("ɔɹ", "ao", "r-coloured vowel: its vowel"), ("ɔːɹ", "ao", "r-coloured vowel: its vowel"),
    ("oɹ", "ao", "r-coloured vowel: like ɔɹ"), ("oːɹ", "ao", "r-coloured vowel: like ɔɹ"),
    ("ɛɹ", "eh", "r-coloured vowel: its vowel"), ("eɹ", "eh", "r-coloured vowel: its vowel"),
    ("ɪɹ", "ih", "r-coloured vowel: its vowel"), ("iɹ", "ih", "r-coloured vowel: its vowel"),
    ("ʊɹ", "uh", "r-coloured vowel: its vowel"), ("ʉɹ", "uh", "r-coloured vowel: like ʊɹ"),
    ("ʌɹ", "er", "r-coloured: like er"), ("əɹ", "er", "r-coloured: like er"),
    ("ə˞", "er", "r-coloured: like er"), ("ɜ˞", "er", "r-coloured: like er"),
    # espeak quirks
    ("a:", "aa", "espeak en-gb-scotland writes the length with an ASCII colon"),
    ("aa", "aa", "espeak en-029 BATH vowel"), ("ææ", "ae", "espeak en-029 TRAP vowel"),
    ("iʲ", "iy", "espeak-ng --ipa --sep prints its palatal glide attached to the vowel"),
    ("ɪʲ", "ih", "espeak-ng --ipa --sep prints its palatal glide attached to the vowel"),
    ("eʲ", "ey", "espeak-ng --ipa --sep prints its palatal glide attached to the vowel"),
    ("ᵻʲ", "ih", "espeak-ng --ipa --sep prints its palatal glide attached to the vowel"),
    # aligner silences
    ("sil", "sil", "silence (MFA)"), ("sp", "sil", "short pause (MFA)"), ("spn", "sil", "spoken noise (MFA)"),
]
IPA_CONSONANTS = [
    ("p", "p", "the segment builder splits it into closure and release"),
    ("b", "b", "the segment builder splits it into closure and release"),
    ("t", "t", ""), ("d", "d", ""), ("ʈ", "t", ""), ("ɖ", "d", ""), ("k", "k", ""), ("ɡ", "g", ""),
    ("g", "g", "ASCII g for ɡ"), ("c", "k", "palatal stop (MFA, before front vowels)"),
    ("ɟ", "g", "palatal stop (MFA, before front vowels)"), ("ɢ", "g", "uvular stop"),
    ("ʔ", "q", "glottal stop"),
    ("m", "m", ""), ("ɱ", "f", "labiodental nasal (info): the lower lip touches the teeth as for f"),
    ("n", "n", ""), ("ɳ", "n", ""), ("ɲ", "n", "palatal nasal (MFA, before front vowels)"), ("ŋ", "ng", ""),
    ("ɴ", "ng", ""),
    ("f", "f", ""), ("v", "v", ""), ("ɸ", "ipa_ɸ", "bilabial fricative: lips nearly together, not sealed"),
    ("β", "ipa_β", "bilabial fricative: lips nearly together, not sealed"),
    ("ʋ", "v", "labiodental approximant: the lower lip at the upper teeth as for v"),
    ("θ", "th", ""), ("ð", "dh", ""), ("s", "s", ""), ("z", "z", ""), ("ʃ", "sh", ""), ("ʒ", "zh", ""),
    ("ʂ", "sh", ""), ("ʐ", "zh", ""), ("ɕ", "sh", ""), ("ʑ", "zh", ""),
    ("ç", "hh", "palatal h (MFA: h before j)"), ("x", "k", "velar fricative (loch): the tongue back of k"),
    ("ɣ", "g", ""), ("χ", "k", ""), ("ʁ", "ipa_ʁ", "uvular r (French, German): the tongue back, lips free"),
    ("h", "hh", ""), ("ɦ", "hh", ""),
    ("tʃ", "ch", ""), ("ʧ", "ch", "ligature"), ("dʒ", "jh", ""), ("ʤ", "jh", "ligature"),
    ("ts", "t", ""), ("dz", "d", ""), ("tɕ", "ch", ""), ("dʑ", "jh", ""),
    ("w", "w", ""), ("ʍ", "w", "voiceless w (which)"), ("ɥ", "w", ""), ("j", "y", ""),
    ("ʲ", "y", "espeak's palatal glide between i and a vowel, printed on its own"),
    ("l", "l", ""), ("ɫ", "l", "dark l"), ("ɬ", "l", "voiceless lateral (Welsh names)"), ("ɮ", "l", ""),
    ("ʎ", "l", "palatal lateral (MFA, before front vowels)"), ("əl", "l", "espeak's syllabic l: the consonant"),
    ("ɹ", "r", ""), ("r", "ipa_r", "alveolar trill (Spanish, Italian, Russian...): lips free; English IPA writes ɹ"),
    ("ɻ", "r", ""), ("ʀ", "ipa_ʁ", "uvular trill: as the uvular r"), ("ɾ", "dx", "flap"), ("ɽ", "dx", ""),
    # the rest of the IPA chart (docs/languages.md): own phonemes where no English one looks alike
    ("q", "ipa_q", "uvular stop (ARPAbet and TIMIT q is the glottal stop)"), ("ʙ", "ipa_ʙ", "bilabial trill"),
    ("ħ", "ipa_ħ", "pharyngeal fricative"), ("ʕ", "ipa_ʕ", "pharyngeal approximant"),
    ("ʜ", "ipa_ħ", "epiglottal fricative: as the pharyngeal"), ("ʢ", "ipa_ʕ", "epiglottal: as the pharyngeal"),
    ("ʡ", "q", "epiglottal stop: no oral target, as the glottal stop"),
    ("ʝ", "y", "palatal fricative: the tongue body and spread lips of the palatal glide"),
    ("ɰ", "g", "velar approximant: the tongue back of a velar, lips free"),
    ("ɭ", "l", "retroflex lateral: as l"), ("ʟ", "g", "velar lateral: the tongue back of a velar"),
    ("ɺ", "l", "lateral flap: as l"), ("ⱱ", "v", "labiodental flap: the lower lip strikes the upper teeth as for v"),
    ("ɧ", "sh", "sj-sound (Swedish): protruded lips as sh"),
]
# Symbols other than English's that front-ends emit as one phoneme: diphthongs, affricates, and the
# names espeak-ng 1.51 gives phonemes of its non-English tables that have no IPA name (measured: the
# digits and a sentence in every voice).
IPA_LANGUAGE_ROWS = [
    ("ai", "ay", "diphthong (German, Spanish...)"), ("au", "aw", "diphthong"), ("ɔʏ", "oy", "diphthong (German)"),
    ("ɔy", "oy", "diphthong"), ("oi", "oy", "diphthong"), ("ou", "ow", "diphthong"),
    ("pf", "p", "affricate (German): its bilabial closure and release; the f is too brief to show"),
    ("bv", "b", "affricate: its bilabial closure and release"),
    ("ʈʂ", "ch", "retroflex affricate (Mandarin zh)"), ("ɖʐ", "jh", "retroflex affricate"),
    ("ɟʝ", "y", "palatal affricate (MFA Spanish): the tongue body and spread lips of the palatal glide"),
    ("cç", "k", "palatal affricate"), ("tɬ", "t", "lateral affricate"), ("dɮ", "d", "lateral affricate"),
    ("kx", "k", "velar affricate"), ("ʦ", "t", "ligature ts"), ("ʣ", "d", "ligature dz"),
    ("ʨ", "ch", "ligature tɕ"), ("ʥ", "jh", "ligature dʑ"),
    ("ε", "eh", "Greek epsilon for ɛ (espeak-ng)"),
    ("tS", "ch", "espeak-ng name without IPA (ky)"), ("dZ", "jh", "espeak-ng name without IPA"),
    ("S", "sh", "espeak-ng name without IPA (ky)"), ("X", "k", "espeak-ng name without IPA (lb): velar fricative"),
    ("A", "aa", "espeak-ng name without IPA (ga)"), ("t[", "t", "espeak-ng dental t without IPA (ky)"),
    ("t`", "t", "espeak-ng retroflex t without IPA (am)"), ("r.", "r", "espeak-ng retroflex r without IPA"),
    ("r#", "r", "espeak-ng voiceless r without IPA (is)"), ("tl#", "t", "espeak-ng voiceless tl without IPA (is)"),
    ("i.", "ih", "espeak-ng apical vowel without IPA (Mandarin zhi, shi)"),
    ("s.", "sh", "espeak-ng retroflex s without IPA (Mandarin)"), ("n^", "n", "espeak-ng palatal nasal without IPA"),
    ("l-", "l", "espeak-ng syllabic l without IPA (ky)"),
    ("?", "q", "espeak-ng glottal stop without IPA (om)"), ("Φ", "ipa_ɸ", "Greek Phi for ɸ (espeak-ng om)"),
    ("ä", "ae", "open central a (espeak-ng ja): as a"),
    ("ᵐ", "m", "prenasalisation printed on its own (espeak-ng si)"), ("ⁿ", "n", "prenasalisation on its own"),
    ("ᵑ", "ng", "prenasalisation on its own"),
    # nasal vowels written with a precomposed tilde (one code point): their oral vowel, as the
    # combining tilde (U+0303) is removed
    ("ã", "ae", "nasal a (precomposed)"), ("ẽ", "ey", "nasal e (precomposed)"), ("ĩ", "iy", "nasal i (precomposed)"),
    ("õ", "ow", "nasal o (precomposed)"), ("ũ", "uw", "nasal u (precomposed)"), ("ỹ", "ipa_y", "nasal y (precomposed)"),
]
# Every symbol of the IPA chart (pulmonic consonants, other symbols, vowels): each has a row.
IPA_CHART = ("p b t d ʈ ɖ c ɟ k ɡ q ɢ ʔ m ɱ n ɳ ɲ ŋ ɴ ʙ r ʀ ⱱ ɾ ɽ ɸ β f v θ ð s z ʃ ʒ ʂ ʐ ç ʝ x ɣ χ ʁ ħ ʕ h ɦ "
             "ɬ ɮ ʋ ɹ ɻ j ɰ l ɭ ʎ ʟ ʍ w ɥ ʜ ʢ ʡ ɕ ʑ ɺ ɧ "
             "i y ɨ ʉ ɯ u ɪ ʏ ʊ e ø ɘ ɵ ɤ o ə ɛ œ ɜ ɞ ʌ ɔ æ ɐ a ɶ ɑ ɒ").split()
# Marks removed only when a label is not in the table as written (the fallback, docs/languages.md):
# length, tones and phonation, articulatory details that do not change the mouth.
IPA_FALLBACK_IGNORE = ("ːˤˀᵝⁿˡ˞"  # long, pharyngealised, glottalised, compressed, nasal/lateral release, rhotic
                       "ʷ"  # labialised, where the table has no labialised partner (pʷ, mʷ, fʷ: the lips close anyway)
                       "-#.[`^;:!/\""  # the marks of espeak-ng mnemonics it prints for phonemes without IPA (y-)
                       "˥˦˧˨˩"  # tone letters
                       "\u0300\u0301\u0302\u0304\u030b\u030c\u030f"  # tone diacritics
                       "\u0308\u033d\u0339\u031c\u0324\u0330\u033c\u033a\u033b\u0334\u0348")
# centralised, mid-centralised, more/less rounded, breathy, creaky, linguolabial, apical, laminal,
# velarised/pharyngealised, strong articulation
# Pieces passed over in a label split into several: a glide or glottal onset before the vowel.
IPA_FALLBACK_SKIP = "ʔhjwɥʲ"
# For a model without the ipa_ phonemes (a model of one's own made from an older `lipsync model dump`):
# the English phoneme each stands in for, so that the ipa set still loads against it, mapping the
# labels it mapped before as before (ø -> ow, œ -> ao, ʏ -> uh, ɸ -> f, β -> v, r ʁ ʀ -> r).
IPA_PHONEME_SUBSTITUTES = {
    "ipa_y": "uw", "ipa_ʏ": "uh", "ipa_ø": "ow", "ipa_œ": "ao", "ipa_ɶ": "ao", "ipa_ɯ": "uw", "ipa_ɤ": "ow",
    "ipa_ɸ": "f", "ipa_β": "v", "ipa_ʙ": "b", "ipa_r": "r", "ipa_q": "k", "ipa_ʁ": "r", "ipa_ħ": "hh",
    "ipa_ʕ": "hh",
}
# A labialised consonant stands in as its plain partner (as ʷ was removed before it had one).
IPA_PHONEME_SUBSTITUTES.update({l: IPA_PHONEME_SUBSTITUTES.get(p, p) for p, l in LABIALISED.items()})
# Diacritics and marks removed before lookup. Length (ː) is not among them.
IPA_IGNORE = ("ˈˌˑ"           # stress marks, half-long
              "\u0361\u035c\u200d"  # tie bars; the zero-width joiner of espeak-ng --ipa=2
              "\u0329\u030d\u032f"  # syllabic below/above, non-syllabic (n̩ -> n, ɫ̩ -> ɫ)
              "ʰˠʼ"           # aspiration, velarisation, ejective (pʰ -> p); labialisation kʷ is a phoneme
              "\u032a\u0303\u031a\u0325\u030a\u031d\u031e\u031f\u0320\u0318\u0319\u0306")
# dental (t̪), nasalised (ɑ̃, ɾ̃), unreleased, voiceless, raised/lowered/advanced/retracted, ATR, extra-short


def ipa_phones():
    rows = []
    for label, target, note in IPA_VOWELS:
        rows.append((label, target, note))
        long_label = label + "ː"
        if long_label in IPA_LONG_OVERRIDES:
            t, n = IPA_LONG_OVERRIDES[long_label]
            rows.append((long_label, t, n))
        else:
            rows.append((long_label, target, "long: as the short vowel"))
    rows += IPA_OTHER_VOWELS
    rows += IPA_CONSONANTS
    rows += IPA_LANGUAGE_ROWS
    # Labialised consonants (kʷ, ɡʷ, tʷ...): the consonant's labialised partner, with rounded lips.
    for label, target, note in IPA_CONSONANTS:
        if len(label) == 1 and target in LABIALISED:
            rows.append((label + "ʷ", LABIALISED[target], "labialised: the consonant with rounded lips"))
            # long (geminate): the fallback would remove ʷ with ː
            rows.append((label + "ʷː", LABIALISED[target], "long labialised: as the labialised consonant"))
    # MFA palatalises consonants before front vowels (bʲ, tʲ, mʲ...): the consonant.
    for label, target, note in IPA_CONSONANTS:
        if len(label) == 1 and label not in ("ʲ", "j", "ʔ", "h", "ɦ", "ç") and target != "sil":
            rows.append((label + "ʲ", target, "palatalised (MFA): the consonant"))
    return rows


# espeak-ng's own phoneme mnemonics (espeak-ng -x, and the id.string of
# espeakEVENT_PHONEME events), for the English voices en, en-us, en-gb-x-rp,
# en-gb-scotland, en-gb-x-gbclan, en-gb-x-gbcwmd, en-029, en-us-nyc: every
# phoneme of the phoneme tables those voices use (base1, consonants, en and
# its variants).
ESPEAK = [
    # pauses
    ("_", "sil", "short pause"), ("_:", "sil", "pause"), ("_!", "sil", "pause"), ("_|", "sil", "pause"),
    ("_::", "sil", "long pause"), ("_;_", "sil", "pause"), ("_^_", "sil", "language switch"),
    ("_X1", "sil", "pause"), ("||", "sil", "word boundary pause"),
    # vowels
    ("@", "ax", ""), ("@-", "ax", "short schwa"), ("@2", "ax", "unstressed schwa"), ("@5", "ax", "unstressed schwa"),
    ("@/", "ax", ""), ("@#", "ax", ""), ("@L", "l", "syllabic l: the consonant"),
    ("3", "er", "lettER vowel (ɚ; ə in non-rhotic voices)"), ("3:", "er", "NURSE"),
    ("IR", "er", "r-coloured"), ("VR", "er", "r-coloured"),
    ("a", "ae", "TRAP"), ("a/", "ae", ""), ("aa", "aa", "BATH (æ in en-us, a or ɑː elsewhere): open"),
    ("a#", "ax", "reduced a (about): weak like schwa"), ("a2", "ax", "reduced a"), ("a#2", "ax", "reduced a"),
    ("A:", "aa", "PALM"), ("a:", "aa", "en-gb-scotland BATH"), ("A@", "aa", "START"), ("A#", "aa", ""), ("A~", "aa", "nasal vowel (loan words)"),
    ("E", "eh", ""), ("E#", "eh", ""), ("E2", "eh", ""), ("e", "ey", "close-mid e"), ("e:", "ey", ""),
    ("e#", "eh", ""), ("e@", "eh", "SQUARE: the nearest vowel"),
    ("I", "ih", ""), ("I#", "ih", "reduced i (ᵻ)"), ("I2", "ih", ""), ("I2#", "ih", ""),
    ("i", "iy", "happY"), ("i:", "iy", ""), ("i@", "ih", "NEAR: the nearest vowel"), ("i@3", "ih", "NEAR (ɪɹ)"),
    ("0", "aa", "LOT (ɒ; ɑː in en-us)"), ("0#", "aa", ""), ("02", "aa", ""),
    ("O", "ao", ""), ("O:", "ao", "THOUGHT"), ("O2", "ao", ""), ("O@", "ao", "NORTH"), ("o@", "ao", "FORCE"),
    ("O~", "ao", "nasal vowel (loan words)"), ("o", "ow", ""), ("o:", "ow", ""), ("oU", "ow", "GOAT"),
    ("oU#", "ow", ""), ("U", "uh", ""), ("U@", "uh", "CURE: the nearest vowel"), ("u", "uw", ""), ("u:", "uw", ""),
    ("V", "ah", "STRUT"),
    ("aI", "ay", ""), ("aI2", "ay", ""), ("aI3", "ay", "triphthong (fire): its diphthong"),
    ("aI@", "ay", "triphthong (fire): its diphthong"), ("aU", "aw", ""), ("aU@", "aw", "triphthong (hour): its diphthong"),
    ("eI", "ey", ""), ("OI", "oy", ""),
    # syllabic consonants
    ("m-", "m", "syllabic m"), ("n-", "n", "syllabic n"), ("N-", "ng", "syllabic ng"), ("l-", "l", "syllabic l"),
    ("r-", "r", "linking r"),
    # consonants
    ("p", "p", "the segment builder splits it into closure and release"), ("p-", "p", ""), ("ph", "p", ""),
    ("b", "b", "the segment builder splits it into closure and release"),
    ("t", "t", ""), ("t-", "t", ""), ("t2", "t", ""), ("t#", "dx", "flap (en-us)"), ("t[", "t", "dental t"),
    ("d", "d", ""), ("d#", "d", ""), ("d[", "d", "dental d"), ("k", "k", ""), ("k-", "k", ""), ("kh", "k", ""),
    ("k#", "k", ""), ("c", "k", "palatal stop"), ("c2", "k", ""), ("g", "g", ""), ("g-", "g", ""),
    ("?", "q", "glottal stop"), ("m", "m", ""), ("n", "n", ""), ("n.", "n", ""), ("n^", "n", "palatal nasal"),
    ("N", "ng", ""), ("f", "f", ""), ("v", "v", ""), ("v#", "v", ""), ("B", "v", "bilabial fricative"),
    ("T", "th", ""), ("D", "dh", ""), ("s", "s", ""), ("s2", "s", ""), ("z", "z", ""), ("z#", "z", ""),
    ("z/2", "z", ""), ("S", "sh", ""), ("s.", "sh", ""), ("s;", "sh", ""), ("S;", "sh", ""), ("Z", "zh", ""),
    ("z.", "zh", ""), ("z;", "zh", ""), ("Z;", "zh", ""), ("tS", "ch", ""), ("tS;", "ch", ""), ("dZ", "jh", ""),
    ("dZ;", "jh", ""), ("ts", "t", ""), ("dz", "d", ""), ("h", "hh", ""), ("C", "hh", "palatal fricative"),
    ("x", "k", "velar fricative (loch): the tongue back of k"), ("X", "k", "uvular fricative"),
    ("j", "y", ""), (";", "y", "palatal glide espeak inserts after i before a vowel"),
    ("w", "w", ""), ("w#", "w", "voiceless w (which)"), ("w/", "w", ""),
    ("l", "l", ""), ("l/", "l", ""), ("l/2", "l", ""), ("l/3", "l", ""), ("l^", "l", ""), ("l.", "l", ""),
    ("L", "l", ""), ("L/", "l", ""), ("l#", "l", "voiceless lateral (Welsh names)"),
    ("r", "r", ""), ("r/", "r", ""), ("R", "r", ""), ("R2", "r", ""), ("R3", "r", ""), ('r"', "r", ""),
    ("r.", "r", ""), ("*", "dx", "tap"), ("**", "dx", "tap"),
]
ESPEAK_IGNORE = "',%="  # stress marks in espeak-ng -x output

# SAMPA as MBROLA's English voices use it: en1 (British, the SAMPA of
# Wells) and us1/us2/us3 (American variant: i A O u EI AI r= 4 p_h ...).
SAMPA = [
    ("_", "sil", "MBROLA silence"), ("#", "sil", "silence"),
    ("p", "p", "the segment builder splits it into closure and release"), ("p_h", "p", "aspirated (us1)"),
    ("b", "b", "the segment builder splits it into closure and release"),
    ("t", "t", ""), ("t_h", "t", "aspirated (us1)"), ("d", "d", ""), ("4", "dx", "flap (us1)"),
    ("k", "k", ""), ("k_h", "k", "aspirated (us1)"), ("g", "g", ""), ("?", "q", "glottal stop"),
    ("tS", "ch", ""), ("dZ", "jh", ""), ("ts", "t", ""), ("dz", "d", ""),
    ("f", "f", ""), ("v", "v", ""), ("T", "th", ""), ("D", "dh", ""), ("s", "s", ""), ("z", "z", ""),
    ("S", "sh", ""), ("Z", "zh", ""), ("h", "hh", ""), ("x", "k", "velar fricative (loch)"),
    ("C", "hh", "palatal fricative"), ("G", "g", ""), ("W", "w", "voiceless w"),
    ("m", "m", ""), ("m=", "m", "syllabic m"), ("n", "n", ""), ("n=", "n", "syllabic n"), ("N", "ng", ""),
    ("N=", "ng", "syllabic ng"), ("F", "f", "labiodental nasal: the lip-teeth contact of f"),
    ("l", "l", ""), ("l=", "l", "syllabic l"), ("5", "l", "dark or syllabic l (en1)"), ("K", "l", ""),
    ("r", "r", ""), ("r\\", "r", "X-SAMPA ɹ"), ("R", "r", ""), ("w", "w", ""), ("j", "y", ""),
    ("i:", "iy", ""), ("i", "iy", ""), ("I", "ih", ""), ("1", "ih", ""), ("e", "eh", "DRESS in British SAMPA"),
    ("e:", "ey", ""), ("E", "eh", ""), ("E:", "eh", ""), ("{", "ae", ""), ("a", "ae", ""), ("a:", "aa", ""),
    ("A:", "aa", ""), ("A", "aa", "us1 PALM/LOT"), ("Q", "aa", "LOT (ɒ)"), ("O:", "ao", ""), ("O", "ao", ""),
    ("o", "ow", ""), ("o:", "ow", ""), ("U", "uh", ""), ("u:", "uw", ""), ("u", "uw", ""), ("}", "uw", ""),
    ("}:", "uw", ""), ("V", "ah", ""), ("6", "ah", "ɐ"), ("@", "ax", ""), ("3:", "er", ""), ("3", "er", ""),
    ("r=", "er", "us1 NURSE (her)"), ("@`", "er", "X-SAMPA ɚ"), ("3`", "er", "X-SAMPA ɝ"), ("3`:", "er", ""),
    ("2", "ow", ""), ("9", "ao", ""),
    ("eI", "ey", ""), ("EI", "ey", "us1"), ("aI", "ay", ""), ("AI", "ay", "us1"), ("OI", "oy", ""),
    ("oI", "oy", ""), ("@U", "ow", ""), ("oU", "ow", ""), ("aU", "aw", ""),
    ("I@", "ih", "centring diphthong: the nearest vowel"), ("i@", "ih", "centring diphthong: the nearest vowel"),
    ("e@", "eh", "centring diphthong: the nearest vowel"), ("E@", "eh", "centring diphthong: the nearest vowel"),
    ("U@", "uh", "centring diphthong: the nearest vowel"),
    ("aI@", "ay", "triphthong: its diphthong"), ("aU@", "aw", "triphthong: its diphthong"),
]
SAMPA_IGNORE = "\"%'"  # SAMPA stress marks " and %, and ' (X-SAMPA palatalisation)

PHONE_SETS = [
    {
        "name": "arpabet",
        "description": (
            "ARPAbet as CMUdict, the Montreal Forced Aligner english_us_arpa model and pocketsphinx write it: "
            "the 39 CMUdict phones with stress digits 0/1/2, extended ARPAbet (AX AXR IX UX DX EL EM EN ENG NX Q WH) "
            "and the aligners' silences (SIL, SP, SPN, +NSN+, +SPN+). Case-insensitive. Stress digits are part of "
            "the table because CMUdict writes schwa as AH0."),
        "case_sensitive": False, "ignore_characters": "", "rows": arpabet_phones(),
        "source": "CMUdict (cmudict-0.7b phone list), extended ARPAbet, MFA english_us_arpa, pocketsphinx-en-us",
        "normalisation": "ASCII case-insensitive; nothing removed (the stress digits 0, 1, 2 are listed).",
    },
    {
        "name": "radio",
        "description": (
            "Festival's and flite's 'radio' phone set (cmu_us_* and kal voices, CMU ARCTIC .lab files): lowercase "
            "ARPAbet without stress, plus ax axr dx el em en hv nx and the silences pau, h#, brth. Case-sensitive."),
        "case_sensitive": True, "ignore_characters": "", "rows": RADIO,
        "source": "Festival radio_phones.scm, flite cmu_us_kal/cmu_us_slt (`flite -psdur`)",
        "normalisation": "case-sensitive; nothing removed.",
    },
    {
        "name": "timit",
        "description": (
            "The 61 TIMIT .PHN labels. Bilabial closures pcl/bcl are kept (the model's closure phonemes); the "
            "tongue-internal closures tcl dcl kcl gcl are modelled as their stop (the closure is not visible)."),
        "case_sensitive": False, "ignore_characters": "", "rows": TIMIT,
        "source": "TIMIT documentation (phoncode.doc): 61 phone labels",
        "normalisation": "ASCII case-insensitive; nothing removed.",
    },
    {
        "name": "ipa",
        "description": (
            "IPA as espeak-ng prints it for its voices (--ipa, and phoneme events with "
            "espeakINITIALIZE_PHONEME_IPA) and as the Montreal Forced Aligner's IPA models write it, with every "
            "symbol of the IPA chart. Stress marks, tie bars, syllabic marks and articulatory diacritics (ʰ, "
            "dental, nasal) are removed before lookup; length (ː) is kept; a labialised consonant (kʷ) is a "
            "phoneme with rounded lips. A label not in the table falls back: "
            "length, tone and other marks are removed, and a label made of several symbols (an affricate, a "
            "diphthong) is the phoneme of its first symbol, a glide or glottal onset passed over "
            "(docs/languages.md)."),
        "case_sensitive": True, "ignore_characters": IPA_IGNORE, "rows": ipa_phones(),
        "fallback_ignore_characters": IPA_FALLBACK_IGNORE, "fallback_split": True,
        "fallback_skip": IPA_FALLBACK_SKIP, "phoneme_substitutes": IPA_PHONEME_SUBSTITUTES,
        "source": "espeak-ng 1.51 English voices (measured), MFA english_mfa / english_us_mfa / english_uk_mfa "
                  "dictionary phone sets; every symbol of the IPA chart; espeak-ng 1.51's phoneme events in "
                  "all its voices (measured; docs/languages.md)",
        "normalisation": "case-sensitive; removed before lookup: stress ˈ ˌ, half-long ˑ, tie bars U+0361 U+035C, "
                         "zero-width joiner U+200D, syllabic U+0329 U+030D, non-syllabic U+032F, ʰ ˠ ʼ, and the "
                         "diacritics dental U+032A, nasal U+0303, unreleased U+031A, voiceless U+0325 U+030A, "
                         "raised/lowered/advanced/retracted U+031D U+031E U+031F U+0320, ATR U+0318 U+0319, "
                         "extra-short U+0306. Length ː and labialisation ʷ are significant (ʷ is removed in the fallback "
                         "where the consonant has no labialised partner: pʷ, mʷ, fʷ).",
    },
    {
        "name": "espeak",
        "description": (
            "espeak-ng's ASCII phoneme mnemonics for its English voices (espeak-ng -x, and the id.string of "
            "phoneme events): every phoneme of the base1, consonants and en phoneme tables. Case-sensitive; the "
            "stress marks ' , % = are removed."),
        "case_sensitive": True, "ignore_characters": ESPEAK_IGNORE, "rows": ESPEAK,
        "source": "espeak-ng 1.51 phontab (tables base1, consonants, en, en-us, en-sc, en-n, en-rp, en-wm, en-wi, "
                  "en-us-nyc), checked against phoneme events of all English voices",
        "normalisation": "case-sensitive; removed before lookup: ' , % =.",
    },
    {
        "name": "sampa",
        "description": (
            "SAMPA as MBROLA's English voices use it (.pho files): en1 (British SAMPA: i: I e { A: Q O: U u: V 3: @ "
            "eI aI OI @U aU I@ e@ U@ 5) and us1/us2/us3 (i A O u EI AI r= 4 p_h t_h k_h), with a few X-SAMPA "
            "spellings. _ is silence. Case-sensitive; stress marks \" % are removed."),
        "case_sensitive": True, "ignore_characters": SAMPA_IGNORE, "rows": SAMPA,
        "source": "MBROLA en1 and us1 voice documentation; espeak-ng's mbrola translation tables en1 and us",
        "normalisation": "case-sensitive; removed before lookup: \" % '.",
    },
]


def normalise(label, case_sensitive, ignore):
    out = "".join(ch for ch in label if ch not in ignore)
    if not case_sensitive:
        out = "".join(ch.lower() if "A" <= ch <= "Z" else ch for ch in out)
    return out


def build_phone_set(spec):
    phones = {}
    seen = {}
    for label, target, _ in spec["rows"]:
        assert target in INVENTORY, (spec["name"], label, target)
        key = normalise(label, spec["case_sensitive"], spec["ignore_characters"])
        assert not any(ch in spec["ignore_characters"] for ch in label), (spec["name"], label, "ignored character")
        assert key, (spec["name"], label)
        assert key not in seen, (spec["name"], label, seen.get(key))
        seen[key] = label
        phones[label] = target
    table = {
        "format": "lipsync-phone-set",
        "version": 1,
        "name": spec["name"],
        "description": spec["description"],
        "case_sensitive": spec["case_sensitive"],
        "ignore_characters": spec["ignore_characters"],
    }
    for key in ("fallback_ignore_characters", "fallback_split", "fallback_skip", "phoneme_substitutes"):
        if key in spec:
            table[key] = spec[key]
    table["phones"] = phones
    return table


def check_shared_labels():
    """Sets that share a label must map it identically (auto-detection may pick either)."""
    tables = []
    for spec in PHONE_SETS:
        tables.append((spec, {normalise(l, spec["case_sensitive"], spec["ignore_characters"]): t
                              for l, t, _ in spec["rows"]}))
    problems = []
    for i, (a, ta) in enumerate(tables):
        for b, tb in tables[i + 1:]:
            for label, target in ta.items():
                probe = normalise(label, b["case_sensitive"], b["ignore_characters"])
                if probe in tb and tb[probe] != target:
                    problems.append("%s %r -> %s but %s %r -> %s" % (a["name"], label, target, b["name"], probe,
                                                                   tb[probe]))
    return problems


# Labels whose mapping differs between sets on purpose (documented in docs/phone-sets.md).
KNOWN_SHARED_DIFFERENCES = {
    "ipa 'e' -> ey but sampa 'e' -> eh",
    "espeak 'e' -> ey but sampa 'e' -> eh",
    # IPA y is the close front rounded vowel and q the uvular stop; ARPAbet, radio and TIMIT y is the
    # palatal glide (IPA j) and q the glottal stop (IPA ʔ).
    "arpabet 'y' -> y but ipa 'y' -> ipa_y",
    "arpabet 'q' -> q but ipa 'q' -> ipa_q",
    "radio 'y' -> y but ipa 'y' -> ipa_y",
    "timit 'q' -> q but ipa 'q' -> ipa_q",
    "timit 'y' -> y but ipa 'y' -> ipa_y",
    # IPA r is the alveolar trill; the other sets' r is English r (IPA ɹ), rounded.
    "radio 'r' -> r but ipa 'r' -> ipa_r",
    "arpabet 'r' -> r but ipa 'r' -> ipa_r",
    "timit 'r' -> r but ipa 'r' -> ipa_r",
    "ipa 'r' -> ipa_r but espeak 'r' -> r",
    "ipa 'r' -> ipa_r but sampa 'r' -> r",
}


# ---------------------------------------------------------------------------
# Documentation of the phone sets (docs/phone-sets.md).
# ---------------------------------------------------------------------------

def md_escape(text):
    return text.replace("|", "\\|").replace("`", "\\`") if text else text


def md_code(label):
    # Show invisible or combining characters as code points too.
    shown = label.replace("|", "\\|")
    return "`" + shown + "`" if "`" not in label else "`` " + shown + " ``"


def build_phone_sets_doc():
    lines = [
        "# Phone sets",
        "",
        "<!-- Generated by tools/make_default_model.py: edit the script, not this file. -->",
        "",
        "A phone set maps the labels of an aligner or a TTS front-end to the phonemes of the articulation",
        "model (docs/model.md). The tables are data: `data/phonesets/<name>.json`, embedded in the binary.",
        "",
        "## File format",
        "",
        "```json",
        "{",
        '  "format": "lipsync-phone-set",',
        '  "version": 1,',
        '  "name": "arpabet",',
        '  "description": "source and conventions",',
        '  "case_sensitive": false,',
        '  "ignore_characters": "",',
        '  "phones": {"AA": "aa", "AA0": "aa", "SIL": "sil"}',
        "}",
        "```",
        "",
        "- `case_sensitive`: `false` compares labels and keys after lower-casing ASCII letters.",
        "- `ignore_characters`: code points removed from a label (and from the keys) before lookup, such as",
        "  stress marks. Keys that become equal after normalisation are an error.",
        "- `phones`: label → model phoneme. Every phoneme named must exist in the model.",
        "- An empty label is always silence. A label that is empty only after normalisation is unknown.",
        "- Optional, for a label the table lacks (the `ipa` set uses them; docs/languages.md):",
        "  `fallback_ignore_characters` (code points then removed, such as length and tone marks),",
        "  `fallback_split` (`true`: a label made of several of the table's labels, longest first, is the",
        "  phoneme of the first of them) and `fallback_skip` (labels passed over in such a split when",
        "  another follows: a glide or glottal onset). A label that still matches nothing is unknown.",
        "- Optional `phoneme_substitutes`: model phoneme → the phoneme used instead when the model lacks",
        "  it (the `ipa` set's `ipa_…` phonemes → English ones, for models made before they existed).",
        "",
        "Automatic detection tries the sets in the order arpabet, radio, timit, ipa, espeak, sampa and takes",
        "the first that knows every label of the input. Where two sets share a label they map it to the same",
        "phoneme, with one exception: `e` is `ey` in IPA and espeak (close-mid e, the quality of FACE) but",
        "`eh` in SAMPA (British SAMPA writes DRESS as `e`). A SAMPA file nearly always holds a label the",
        "earlier sets lack (`{`, `@U`, `_`, ...), so detection is not misled in practice; name the set to be",
        "sure.",
        "",
        "## Conventions shared by all sets",
        "",
        "- Silences, pauses, breath and noise labels map to `sil`.",
        "- Bilabial stops `p b` map to the release phonemes; when the input has no separate closure the",
        "  segment builder splits the segment into closure (`pcl`/`bcl`) and release. TIMIT's own `pcl bcl`",
        "  map to the closures; its tongue closures `tcl dcl kcl gcl` map to the stop itself, since the",
        "  closure happens inside the mouth (paper, Section 4).",
        "- Diphthongs map to the model's diphthong phonemes (`ay ey oy aw ow`); centring diphthongs",
        "  (NEAR, SQUARE, CURE) and triphthongs (fire, hour) map to the nearest vowel or diphthong.",
        "- Syllabic consonants map to their consonant; flaps to `dx`; glottal stops to `q`.",
        "- r-coloured vowels written as one symbol (espeak's `ɑːɹ`, `ɪɹ`) map to their vowel; the rhotic",
        "  vowels `ɚ ɝ ɜ` and ARPAbet `ER AXR` map to `er`.",
        "- Long vowels map to the tense vowel (`iː` → `iy`, `uː` → `uw`); length itself is not visible.",
        "- Consonants outside English map to the English phoneme with the same visible articulation:",
        "  `x` → `k`, `ɬ` → `l`, `ɱ` → `f`. Symbols no English phoneme looks like (front rounded and back",
        "  unrounded vowels, bilabial fricatives and trill, the alveolar trill `r`, uvulars `q ʁ ʀ`,",
        "  pharyngeals) have phonemes of their own, `ipa_…` (docs/languages.md).",
        "- Unstressed ARPAbet `AH0` is CMUdict's schwa and maps to the weak `ax`; espeak's reduced `a#`",
        "  (about) also maps to `ax`, while IPA `ɐ` (MFA's British STRUT) maps to `ah`.",
        "",
    ]
    for spec in PHONE_SETS:
        lines += [
            "## %s" % spec["name"],
            "",
            spec["description"],
            "",
            "- Source: %s." % spec["source"],
            "- Normalisation: %s" % spec["normalisation"],
            "- Labels: %d." % len(spec["rows"]),
            "",
            "| label | phoneme | note |",
            "|---|---|---|",
        ]
        for label, target, note in spec["rows"]:
            lines.append("| %s | %s | %s |" % (md_code(label), target, md_escape(note)))
        lines.append("")
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# docs/languages.md: the generated part (between the markers), the rest is prose.
# ---------------------------------------------------------------------------

LANGUAGES_BEGIN = "<!-- BEGIN generated by tools/make_default_model.py: edit the script, not this part. -->"
LANGUAGES_END = "<!-- END generated part -->"


def feature_summary(name):
    f = features_of(name)
    if f.get("type") == "silence":
        return "silence"
    if "place" in f:
        parts = [f["voicing"], f["place"], f["manner"]]
        parts += [k for k in ("sibilant", "rhotic") if f.get(k)]
        if "rounding" in f:
            parts.append(f["rounding"])
        if f.get("labialised"):
            parts.append("labialised")
        return " ".join(parts)
    if f.get("diphthong"):
        q = lambda v: "%s %s %s" % (v["height"], v["backness"], v["rounding"])
        return "diphthong: %s → %s" % (q(f["onset"]), q(f["offglide"]))
    parts = [f["height"], f["backness"], f["rounding"]]
    parts += [k for k in ("tense", "reduced", "rhotic") if f.get(k)]
    return " ".join(parts)


# The columns of the feature -> channel table: one per channel group (left and right are equal).
TABLE_COLUMNS = [
    ("jaw", "jaw_rotation"), ("tongue raise", "tongue_raise"), ("tongue out", "tongue_protrusion"),
    ("sphincter upper", OOU), ("sphincter lower", OOL), ("mentalis", MENT),
    ("spread (risorius)", "risorius_left"), ("smile (zygomaticus)", "zygomaticus_major_left"),
    ("lower lip down", "depressor_labii_inferioris_left"), ("upper lip up", "levator_labii_superioris_left"),
    ("corners down", "depressor_anguli_oris_left"),
]


def build_languages_tables():
    model = build_model()
    rows = {label: (target, note) for label, target, note in ipa_phones()}
    lines = [LANGUAGES_BEGIN, "", "### The IPA chart", "",
             "Every symbol of the chart's pulmonic consonants, other symbols and vowels, the model phoneme the "
             "`ipa` phone set gives it, and that phoneme's features. Phonemes named `ipa_…` exist for other "
             "languages only; the others are the English phonemes whose visible articulation the symbol shares.",
             "", "| symbol | phoneme | its features | note |", "|---|---|---|---|"]
    for symbol in IPA_CHART:
        target, note = rows.get(symbol) or rows[symbol.replace("ɡ", "g")]
        lines.append("| %s | `%s` | %s | %s |" % (md_code(symbol), target, feature_summary(target), md_escape(note)))
    lines += ["", "### What the features do to the channels", "",
              "The targets of every phoneme of the default model, as the rules of docs/model.md compute them "
              "from its features (left and right channels are equal; blank is the channel's rest). Dominance: "
              "the largest α of the phoneme on any channel (closures 100, docs/coarticulation.md).", "",
              "| phoneme | class | features | " + " | ".join(c for c, _ in TABLE_COLUMNS) + " | largest α |",
              "|---|---|---|" + "---|" * (len(TABLE_COLUMNS) + 1)]
    for name in INVENTORY:
        p = model["phonemes"][name]
        cells = []
        for _, ch in TABLE_COLUMNS:
            v = p["targets"].get(ch)
            cells.append("" if v is None else "%.2f" % v)
        alpha = max(d["alpha"] for d in dominance_of(name).values())
        lines.append("| `%s` | %s | %s | %s | %g |" % (name, p["class"], feature_summary(name), " | ".join(cells),
                                                      num(alpha)))
    lines += ["", LANGUAGES_END]
    return "\n".join(lines)


def languages_doc(root):
    """docs/languages.md with its generated part replaced; its prose as it is."""
    path = os.path.join(root, "docs", "languages.md")
    with open(path, encoding="utf-8") as f:
        text = f.read()
    begin, end = text.find(LANGUAGES_BEGIN), text.find(LANGUAGES_END)
    if begin < 0 or end < begin:
        raise SystemExit("docs/languages.md lacks the markers of its generated part")
    return text[:begin] + build_languages_tables() + text[end + len(LANGUAGES_END):]


# ---------------------------------------------------------------------------
# Test fixtures (tests/data/models/): one valid minimal model, and bad ones
# that each break exactly one validation rule.
# ---------------------------------------------------------------------------

def minimal_model():
    return {
        "format": "lipsync-articulation-model",
        "version": 1,
        "name": "minimal",
        "description": "Smallest valid model: two channels and the phonemes sil, aa, pcl, p.",
        "channels": [
            {"name": "lips", "kind": "muscle", "min": 0.0, "max": 1.0, "rest": 0.0,
             "description": "lip closure, 0 open .. 1 pressed together"},
            {"name": "jaw", "kind": "jaw", "min": 0.0, "max": 1.0, "rest": 0.0,
             "description": "jaw opening, 0 closed .. 1 wide open"},
        ],
        "dominance_defaults": {"alpha": 1.0, "theta_minus_per_s": 20.0, "theta_plus_per_s": 20.0, "c": 1.0,
                               "t_off_ms": 0.0},
        "phonemes": {
            "sil": {"class": "silence", "note": "rest", "dominance": {"alpha": 0.5}},
            "aa": {"class": "vowel", "targets": {"jaw": 0.8}},
            "pcl": {"class": "closure", "targets": {"lips": 1.0},
                    "channel_dominance": {"lips": {"alpha": 8.0, "theta_minus_per_s": 40.0,
                                                   "theta_plus_per_s": 40.0}}},
            "p": {"class": "release", "closure": "pcl", "targets": {"lips": 0.3, "jaw": 0.1}},
        },
        "arkit": {
            "jawOpen": {"weights": {"jaw": 1.0}, "note": "jaw opening"},
            "mouthClose": {"weights": {"lips": 0.5}},
        },
    }


def bad_models():
    def edit(description, change):
        m = minimal_model()
        m["description"] = "INVALID: " + description
        change(m)
        return m

    def set_path(*path_and_value):
        *path, value = path_and_value

        def change(m):
            node = m
            for key in path[:-1]:
                node = node[key]
            node[path[-1]] = value
        return change

    def delete(*path):
        def change(m):
            node = m
            for key in path[:-1]:
                node = node[key]
            del node[path[-1]]
        return change

    def rename_sil(m):
        m["phonemes"] = {("pause" if k == "sil" else k): v for k, v in m["phonemes"].items()}

    def duplicate_channel(m):
        m["channels"][1]["name"] = "lips"

    return [
        ("bad_target_out_of_range.json", edit("target of aa on 'jaw' is 1.5, outside [0, 1]",
                                              set_path("phonemes", "aa", "targets", "jaw", 1.5))),
        ("bad_unknown_channel.json", edit("aa names a target for channel 'lipz', which does not exist",
                                          set_path("phonemes", "aa", "targets", "lipz", 0.2))),
        ("bad_alpha.json", edit("sil has alpha 0; alpha must be > 0",
                                set_path("phonemes", "sil", "dominance", "alpha", 0.0))),
        ("bad_exponent.json", edit("aa has c = 0.5; c must be in [1, 4]",
                                   set_path("phonemes", "aa", "dominance", {"c": 0.5}))),
        ("bad_release_without_closure.json", edit("release p has no 'closure'", delete("phonemes", "p", "closure"))),
        ("bad_missing_sil.json", edit("no phoneme 'sil' (it is called 'pause')", rename_sil)),
        ("bad_closure_not_closure_class.json", edit("p names the vowel aa as its closure",
                                                    set_path("phonemes", "p", "closure", "aa"))),
        ("bad_closure_on_non_release.json", edit("the vowel aa has a 'closure' field",
                                                 set_path("phonemes", "aa", "closure", "pcl"))),
        ("bad_theta.json", edit("pcl has theta_plus_per_s = -1 on 'lips'; rates must be > 0",
                                set_path("phonemes", "pcl", "channel_dominance", "lips", "theta_plus_per_s", -1.0))),
        ("bad_t_off.json", edit("aa has t_off_ms = 600; peak offsets must be within ±500 ms",
                                set_path("phonemes", "aa", "dominance", {"t_off_ms": 600.0}))),
        ("bad_class.json", edit("aa has class 'vowl'", set_path("phonemes", "aa", "class", "vowl"))),
        ("bad_unknown_field.json", edit("aa has an unknown field 'target' (singular)",
                                        set_path("phonemes", "aa", "target", {"jaw": 0.8}))),
        ("bad_channel_kind.json", edit("channel 'lips' has kind 'skin'", set_path("channels", 0, "kind", "skin"))),
        ("bad_channel_range.json", edit("channel 'jaw' has min 1 and max 0", set_path("channels", 1, "min", 1.0))),
        ("bad_channel_rest.json", edit("channel 'jaw' has rest 2, outside [0, 1]",
                                       set_path("channels", 1, "rest", 2.0))),
        ("bad_duplicate_channel.json", edit("two channels are called 'lips'", duplicate_channel)),
        ("bad_arkit_name.json", edit("ARKit row 'JawOpen' is not Apple's spelling (jawOpen)",
                                     lambda m: m["arkit"].update({"JawOpen": m["arkit"].pop("jawOpen")}))),
        ("bad_arkit_channel.json", edit("ARKit row jawOpen weights channel 'chin', which does not exist",
                                        set_path("arkit", "jawOpen", "weights", "chin", 1.0))),
    ]


# ---------------------------------------------------------------------------
# Output.
# ---------------------------------------------------------------------------

def dump_json(obj):
    return json.dumps(obj, indent=2, ensure_ascii=False) + "\n"


def outputs(root=ROOT):
    files = [(os.path.join("data", "models", "default.json"), dump_json(build_model()))]
    files.append((os.path.join("docs", "languages.md"), languages_doc(root)))
    for spec in PHONE_SETS:
        files.append((os.path.join("data", "phonesets", spec["name"] + ".json"), dump_json(build_phone_set(spec))))
    files.append((os.path.join("docs", "phone-sets.md"), build_phone_sets_doc()))
    files.append((os.path.join("tests", "data", "models", "valid_minimal.json"), dump_json(minimal_model())))
    for name, model in bad_models():
        files.append((os.path.join("tests", "data", "models", name), dump_json(model)))
    return files


def self_check(model):
    """Checks the generated model against the loader's validation rules."""
    channels = {c["name"]: c for c in model["channels"]}
    for name, p in model["phonemes"].items():
        for ch, v in p["targets"].items():
            assert channels[ch]["min"] <= v <= channels[ch]["max"], (name, ch, v)
        doms = [p.get("dominance", {})] + list(p.get("channel_dominance", {}).values())
        for d in doms:
            merged = dict(DEFAULTS)
            merged.update(p.get("dominance", {}))
            merged.update(d)
            assert merged["alpha"] > 0 and merged["theta_minus_per_s"] > 0 and merged["theta_plus_per_s"] > 0
            assert 1 <= merged["c"] <= 4 and abs(merged["t_off_ms"]) <= 500
            # Seven 80 ms segments away the weight must be negligible (< 1 % of α).
            assert math.exp(-min(merged["theta_minus_per_s"], merged["theta_plus_per_s"]) * 0.56) < 0.01, name
        assert (p["class"] == "release") == ("closure" in p), name
    assert model["phonemes"]["sil"]["class"] == "silence"
    # The phonemes of other languages must not change how English renders: the viseme classifier
    # weighs a channel by the largest dominance of closure against other phonemes on it
    # (core/src/visemes.cpp), so no new phoneme may dominate a channel more than an English one does.
    def largest_alpha(names, closure):
        out = {}
        for name in names:
            if (CONSONANTS.get(name, ("",))[0] == "closure") != closure:
                continue
            for ch, d in dominance_of(name).items():
                out[ch] = max(out.get(ch, 0.0), d["alpha"])
        return out
    for closure in (False, True):
        assert largest_alpha(INVENTORY, closure) == largest_alpha(ENGLISH_INVENTORY, closure), closure
    assert sorted(IPA_PHONEME_SUBSTITUTES) == sorted(n for n in INVENTORY if n.startswith("ipa_"))
    assert all(v in ENGLISH_INVENTORY for v in IPA_PHONEME_SUBSTITUTES.values())
    labels = {label for label, _, _ in ipa_phones()}
    missing = [symbol for symbol in IPA_CHART if symbol not in labels and symbol.replace("ɡ", "g") not in labels]
    assert not missing, "IPA chart symbols without a row: " + " ".join(missing)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true",
                        help="do not write; exit 1 if a generated file differs from what would be written")
    parser.add_argument("--root", default=ROOT, help="repository root (default: this script's repository)")
    args = parser.parse_args()

    self_check(build_model())
    problems = [p for p in check_shared_labels() if p not in KNOWN_SHARED_DIFFERENCES]
    if problems:
        print("phone sets disagree on shared labels:\n  " + "\n  ".join(problems), file=sys.stderr)
        return 2

    stale = []
    for rel, text in outputs(args.root):
        path = os.path.join(args.root, rel)
        try:
            with open(path, encoding="utf-8") as f:
                current = f.read()
        except FileNotFoundError:
            current = None
        if current == text:
            continue
        if args.check:
            stale.append(rel)
        else:
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "w", encoding="utf-8", newline="\n") as f:
                f.write(text)
            print("wrote " + rel)
    if stale:
        print("out of date (run python3 tools/make_default_model.py and commit the result):\n  "
              + "\n  ".join(stale), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
