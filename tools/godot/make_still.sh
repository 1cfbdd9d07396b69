#!/usr/bin/env bash
# Stills of the Godot add-on for docs/integrations.md: the LipsyncPlayer node showing a track of
# flite's "Papa bought five more big maps." on lipsyncd's viewer face, at the first closure key frame
# (/p/, lips sealed) and at the widest jaw opening (/aa/), rendered by Godot 3 (Debian's godot3,
# the editor build: godot3-server draws nothing) under Xvfb with Mesa's software GL.
#   tools/godot/make_still.sh [BUILD_DIR]      (default build; writes docs/images/godot-*.png)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."
build=${1:-build}
command -v godot3 >/dev/null && command -v xvfb-run >/dev/null ||
  { echo "make_still.sh needs godot3 and xvfb-run: apt-get install godot3 xvfb xauth" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/project"
printf 'config_version=4\n\n[application]\n\nconfig/name="lipsync still"\n' >"$work/project/project.godot"
cp -r clients/godot/addons "$work/project/"
cp tools/godot/make_still.gd tools/godot/viewer_face_scene.gd tests/integrations/godot/face_fixture.gd "$work/project/"
"$build/clients/cli/lipsync" render tests/data/closures/flite_1.psdur -o "$work/papa.json"
read -r closure_us open_us < <(python3 - "$work/papa.json" <<'PY'
import json, sys
track = json.load(open(sys.argv[1]))
jaw = track["arkit_names"].index("jawOpen")
closure = next(f["t_us"] for f in track["frames"] if f["kind"] == "closure_start")
widest = max(track["frames"], key=lambda f: f["arkit"][jaw])["t_us"]
print(closure, widest)
PY
)
for still in "closure-p $closure_us" "open-aa $open_us"; do
  set -- $still
  LANG=en_US.UTF-8 xvfb-run -a -s "-screen 0 480x360x24" godot3 --audio-driver Dummy --path "$work/project" --resolution 480x360 \
    -s res://make_still.gd -- "$PWD/data/face/viewer_face.json" "$work/papa.json" "$2" "$PWD/docs/images/godot-$1.png"
  echo "docs/images/godot-$1.png: t = $2 us"
done
