#!/usr/bin/env bash
# Regenerates the closure corpus: real TTS timings of sentences full of /p b m/ and /f v/, from
# Festival (kal diphone voice, utt.save.segs: .lab) and flite (slt voice, -psdur), flite also at
# 1.4x speed (short closures). tests/core/closure_real_speech_test.cpp and the face tests measure
# every bilabial and labiodental key frame of these files. Run from anywhere; commit the results.
set -euo pipefail
cd "$(dirname "$0")"

sentences=(
  "Papa bought five more big maps."
  "Bob's mom found a very fine bamboo fence in Memphis."
  "Of my many friends, five have been famous."
  "Jump, pump and bump over the vivid waves."
  "The improvement of the shipment was a big surprise for everybody."
  "Maybe Phoebe will move from Vermont to Miami before February."
)

i=0
for sentence in "${sentences[@]}"; do
  i=$((i + 1))
  festival -b '(voice_kal_diphone)' "(set! u (SynthText \"$sentence\"))" '(utt.save.segs u "-")' \
    > "festival_$i.lab"
  flite -voice slt -psdur -t "$sentence" -o none > "flite_$i.psdur"
  flite -voice slt --setf duration_stretch=0.7 -psdur -t "$sentence" -o none > "flite_fast_$i.psdur"
done
