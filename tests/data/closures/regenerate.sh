#!/usr/bin/env bash
# Regenerates the closure corpus: real timings of sentences full of /p b m/ and /f v/:
#   festival_N.lab        Festival's own timings (kal diphone voice, utt.save.segs)
#   flite_N.psdur         flite's own timings (slt voice, -psdur), flite_fast_N also at 1.4x speed
#   aligned_festival_N.TextGrid, aligned_flite_N.TextGrid
#                         aligned speech: the voices' audio force-aligned to the sentence by
#                         PocketSphinx (`lipsync align`), with an aligner's own boundaries
# tests/core/closure_real_speech_test.cpp, the face and the server tests measure every bilabial and
# labiodental key frame of these files. Needs a build (build/clients/cli/lipsync, or $LIPSYNC).
# Run from anywhere; commit the results.
set -euo pipefail
cd "$(dirname "$0")"
lipsync=${LIPSYNC:-../../../build/clients/cli/lipsync}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT INT TERM

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
  echo "$sentence" | text2wave -eval '(voice_kal_diphone)' -o "$work/festival_$i.wav"
  "$lipsync" align "$work/festival_$i.wav" --text "$sentence" -o "aligned_festival_$i.TextGrid"
  flite -voice slt -t "$sentence" -o "$work/flite_$i.wav"
  "$lipsync" align "$work/flite_$i.wav" --text "$sentence" -o "aligned_flite_$i.TextGrid"
done
