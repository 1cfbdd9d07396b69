#!/bin/sh
# Regenerates the face stills in docs/images/ (docs/face.md, "Export, preview and stills") with
# `lipsync render --still` at subdivision level 1: each phoneme between 0.4 s pauses, the frame
# taken in its middle; the closures after an open /aa/ (/p/ in the middle of its closure, /f/, and
# /m/ held for a second), where the lips must close against the open vowel's jaw. Needs ffmpeg.
#   tools/face/make_stills.sh [path/to/lipsync] [output directory]
set -eu

root=$(cd "$(dirname "$0")/../.." && pwd)
lipsync=${1:-"$root/build/clients/cli/lipsync"}
out=${2:-"$root/docs/images"}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT INT TERM

# name, seconds of the still, then the Festival .lab lines (end time, 100, ARPAbet label).
still() {
  name=$1 at=$2
  shift 2
  printf '#\n' > "$work/$name.lab"
  for line in "$@"; do printf '%s\n' "$line" >> "$work/$name.lab"; done
  "$lipsync" render "$work/$name.lab" ${phone_set:+--phone-set "$phone_set"} --mesh-subdivision 1 \
    --still "$out/face-$name.png" --still-at "$at"
}

still rest 0.60 '0.40 100 pau' '1.20 100 pau'
still p-closure 0.72 '0.40 100 pau' '0.55 100 aa' '1.00 100 p' '1.40 100 pau'
still aa 0.60 '0.40 100 pau' '0.80 100 aa' '1.20 100 pau'
still uw 0.60 '0.40 100 pau' '0.80 100 uw' '1.20 100 pau'
still f 0.68 '0.40 100 pau' '0.55 100 aa' '0.80 100 f' '1.20 100 pau'
still m-held 1.05 '0.40 100 pau' '0.55 100 aa' '1.55 100 m' '1.95 100 pau'

# Other languages (docs/languages.md): French /i/ against /y/ (the jaw and tongue of /i/, rounded
# lips) and nasal /ɔ̃/ (the mouth of /ɔ/); IPA labels, so the ipa set is named (y is ARPAbet's glide).
phone_set=ipa
still ipa-i 0.60 '0.40 100 sil' '0.80 100 i' '1.20 100 sil'
still ipa-y 0.60 '0.40 100 sil' '0.80 100 y' '1.20 100 sil'
still ipa-nasal-o 0.60 '0.40 100 sil' '0.80 100 ɔ̃' '1.20 100 sil'
