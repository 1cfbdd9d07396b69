#!/bin/sh
# Remakes this corpus: Festival's Italian (festvox-italp16k), Czech (festvox-czech-dita),
# Catalan (festvox-ca-ona-hts), Hindi (festvox-hi-nsk) and Finnish (festvox-suopuhe-lj) voices
# speak seven sentences (NAME.wav, NAME.txt: the espeak-ng voice and the transcript; cs_2 and hi_3
# begin with a stop after the pause; fi_2 has the /aː aː m/ of "leipaa aamulla"), with Festival's own segment times matched to the phones
# `lipsync align --voice` gives (NAME.truth.tsv). Needs festival, those voices and a built lipsync:
#   tests/data/recorded_languages/regenerate.sh build/clients/cli/lipsync
set -eu
lipsync=${1:?usage: regenerate.sh LIPSYNC_BINARY}
here=$(dirname "$0")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 "$here/../../../tools/speech/measure_language_alignment.py" "$lipsync" "$work" --corpus "$here"
