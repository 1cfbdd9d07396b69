#!/usr/bin/env bash
# Regenerates the fixtures of tests/formats that come from real tools:
#   flite_*.psdur     flite -psdur output (Debian package flite)
#   festival_*.lab    Festival utt.save.segs output (festival, festvox-kallpc16k)
#   ipa_utf16*.TextGrid  UTF-16 copies of the hand-written ipa_utf8.TextGrid, with a
#                     byte order mark, as Praat writes files with non-ASCII labels
# The other fixtures are written by hand. Run from anywhere; commit the results.
set -euo pipefail
cd "$(dirname "$0")"

flite -voice slt -psdur -t "speech synchronization" -o none > flite_speech_synchronization.psdur
flite -voice slt -psdur -t "Hello world. How are you today?" -o none > flite_two_sentences.psdur

festival -b '(voice_kal_diphone)' '(set! u (SynthText "speech synchronization"))' \
  '(utt.save.segs u "-")' > festival_speech_synchronization.lab
festival -b '(voice_kal_diphone)' '(set! u (SynthText "Mama made a bubble."))' \
  '(utt.save.segs u "-")' > festival_mama.lab

{ printf '\xFE\xFF'; iconv -f UTF-8 -t UTF-16BE ipa_utf8.TextGrid; } > ipa_utf16be.TextGrid
{ printf '\xFF\xFE'; iconv -f UTF-8 -t UTF-16LE ipa_utf8.TextGrid; } > ipa_utf16le.TextGrid
