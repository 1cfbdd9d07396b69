#!/usr/bin/env bash
# Regenerates the LibriVox alignments: read speech from outside the project (Debian's
# pocketsphinx-testdata: five sentences of "Sense and Sensibility" from LibriVox, 16 kHz),
# force-aligned to their transcription by PocketSphinx (`lipsync align`):
#   sense_and_sensibility_NNNN.TextGrid
# The face tests compare the glb, the video frames and lipsyncd's streamed mesh on these; the viseme
# tests check their closure key frames and pauses. Needs a build (build/clients/cli/lipsync, or
# $LIPSYNC) and pocketsphinx-testdata. Run from anywhere; commit the results.
set -euo pipefail
cd "$(dirname "$0")"
lipsync=${LIPSYNC:-../../../build/clients/cli/lipsync}
data=/usr/share/pocketsphinx/test/data/librivox
while read -r line; do
  id=${line##*(}
  id=${id%)}
  text=${line#<s> }
  text=${text%% </s>*}
  "$lipsync" align "$data/$id.wav" --text "$text" -o "sense_and_sensibility_${id##*-}.TextGrid"
done < "$data/transcription"
