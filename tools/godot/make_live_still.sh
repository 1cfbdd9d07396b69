#!/usr/bin/env bash
# A still of the Godot add-on's live mode for docs/integrations.md: flite's WAV of "Papa bought five
# more big maps." played by an AudioStreamPlayer and listen()ed to by the LipsyncPlayer node, which
# sends it live to a real lipsyncd (started here on loopback ports) and shows the frames that come
# back on lipsyncd's viewer face, drawn at the middle of the /ae/ of "maps" (flite's own timings,
# tests/data/closures/flite_1.psdur) by Godot 3 (Debian's godot3, the editor build: godot3-server
# draws nothing) under Xvfb with Mesa's software GL.
#   tools/godot/make_live_still.sh [BUILD_DIR]      (default build; writes docs/images/godot-listen.png)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
build=${1:-build}
command -v godot3 >/dev/null && command -v xvfb-run >/dev/null && command -v flite >/dev/null ||
  { echo "make_live_still.sh needs godot3, xvfb-run and flite: apt-get install godot3 xvfb xauth flite" >&2; exit 1; }
source tests/support/listening_address.sh
sentence="Papa bought five more big maps."
work=$(mktemp -d)
lipsyncd_pid=
trap '[[ -n $lipsyncd_pid ]] && kill "$lipsyncd_pid"; rm -rf "$work"' EXIT
mkdir -p "$work/project"
printf 'config_version=4\n\n[application]\n\nconfig/name="lipsync live still"\n' >"$work/project/project.godot"
cp -r clients/godot/addons "$work/project/"
cp tools/godot/make_live_still.gd tools/godot/viewer_face_scene.gd tests/integrations/godot/face_fixture.gd "$work/project/"
flite -voice slt -t "$sentence" -o "$work/papa.wav"
# The middle of the /ae/ of "maps": flite -psdur gives each phone's end in seconds.
at_us=$(tr ' ' '\n' <tests/data/closures/flite_1.psdur |
  awk -F: '$1 == "ae" { printf "%d\n", (start + $2) / 2 * 1e6; exit } { start = $2 }')
"$build/server/lipsyncd" --listen 127.0.0.1:0 --http-listen 127.0.0.1:0 >"$work/out" 2>"$work/err" &
lipsyncd_pid=$!
wait_for_listening_address "$work/out" 10 "$lipsyncd_pid" >/dev/null || { echo "lipsyncd did not start" >&2; cat "$work/err" >&2; exit 1; }
for _ in $(seq 50); do grep -q '^lipsyncd viewer on ' "$work/out" && break; sleep 0.1; done
viewer=$(sed -n 's/^lipsyncd viewer on \(http:[^ ]*\).*/\1/p' "$work/out")
LANG=en_US.UTF-8 xvfb-run -a -s "-screen 0 480x360x24" godot3 --audio-driver Dummy --path "$work/project" --resolution 480x360 \
  -s res://make_live_still.gd -- "$PWD/data/face/viewer_face.json" "$work/papa.wav" "$viewer" godot-voice "$sentence" \
  "$at_us" "$PWD/docs/images/godot-listen.png"
echo "docs/images/godot-listen.png: t = $at_us us"
