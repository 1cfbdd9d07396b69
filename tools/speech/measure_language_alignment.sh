#!/bin/sh
# Regenerates the alignment accuracy table of docs/languages.md ("Recorded speech in other
# languages"): Festival's Italian, Catalan, Finnish, Czech, Russian, Hindi and English voices,
# four sentences each, aligned by `lipsync align --voice` (and PocketSphinx for English); then
# the same for the six held-out sentences per voice, which no setting was chosen on, and for the
# first two of them apart; then Russian
# against the closures measured on its samples (Festival's Russian labels /p b m/ late), and the
# count, per voice, of the labels that start after their acoustic closure (--label-check).
# Needs festival and festvox-italp16k festvox-ca-ona-hts festvox-suopuhe-lj festvox-czech-dita
# festvox-ru festvox-hi-nsk festvox-kallpc16k; about 40 s.
#   tools/speech/measure_language_alignment.sh [build/clients/cli/lipsync]
set -eu
lipsync=${1:-build/clients/cli/lipsync}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 "$(dirname "$0")/measure_language_alignment.py" "$lipsync" "$work" --markdown
echo
python3 "$(dirname "$0")/measure_language_alignment.py" "$lipsync" "$work" --markdown --held-out
python3 "$(dirname "$0")/measure_language_alignment.py" "$lipsync" "$work" --markdown --held-out --sentences 0,1
echo
python3 "$(dirname "$0")/measure_language_alignment.py" "$lipsync" "$work" --markdown --voices ru --acoustic-closures
python3 "$(dirname "$0")/measure_language_alignment.py" "$lipsync" "$work" --markdown --voices ru --acoustic-closures --held-out
python3 "$(dirname "$0")/measure_language_alignment.py" "$lipsync" "$work" --markdown --voices ru --acoustic-closures --held-out --sentences 0,1
echo
python3 "$(dirname "$0")/measure_language_alignment.py" "$lipsync" "$work" --label-check
python3 "$(dirname "$0")/measure_language_alignment.py" "$lipsync" "$work" --label-check --held-out
