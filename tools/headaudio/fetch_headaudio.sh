#!/usr/bin/env bash
# Fetches HeadAudio (npm `@met4citizen/headaudio`, MIT, by Mika Suominen), the browser's live
# audio-to-viseme peer, into a cache folder for the harness beside this script
# (run_headaudio.mjs, tools/speech/compare_headaudio.py). Nothing of it is committed: the
# default folder, build/headaudio/, is under the ignored build/.
#
# `npm pack` downloads the package's tarball from the npm registry (into the folder, through
# npm's own cache); it is unpacked there as DIR/package/ (modules/processor.mjs, the trained
# model dist/model-en-mixed.bin, LICENSE). A second run finds DIR/package/ complete for the
# version asked and does nothing, so the harness can call it every time.
#
#   tools/headaudio/fetch_headaudio.sh [DIR]      prints DIR/package (absolute) on success
#
# HEADAUDIO_VERSION picks another version (default 0.1.0, the one measured in
# docs/input-formats.md; "latest" asks the registry). Needs npm (Debian: apt-get install npm)
# and the npm registry; exit status 1 with a message saying which is missing.
set -euo pipefail

package_name=@met4citizen/headaudio
version=${HEADAUDIO_VERSION:-0.1.0}
repo_root=$(cd "$(dirname "$0")/../.." && pwd)
dir=${1:-$repo_root/build/headaudio}

fail() {
  echo "fetch_headaudio: $*" >&2
  exit 1
}

command -v npm >/dev/null 2>&1 || fail "npm not found (Debian: apt-get install npm)"
command -v tar >/dev/null 2>&1 || fail "tar not found"
mkdir -p "$dir" || fail "cannot create $dir"
dir=$(cd "$dir" && pwd)
unpacked=$dir/package

# Already here? The unpacked package.json names the version; "latest" always asks the registry.
if [[ "$version" != latest && -f "$unpacked/modules/processor.mjs" && -f "$unpacked/dist/model-en-mixed.bin" ]] &&
  grep -q "\"version\": \"$version\"" "$unpacked/package.json" 2>/dev/null; then
  echo "$unpacked"
  exit 0
fi

# npm pack prints the tarball's file name on its last line of standard output.
if ! tarball=$(cd "$dir" && npm pack --loglevel=error "$package_name@$version" 2>"$dir/npm-pack.log" | tail -n 1) ||
  [[ -z "$tarball" || ! -f "$dir/$tarball" ]]; then
  fail "npm pack $package_name@$version failed (no such version, or the npm registry is not reachable; npm's messages are in $dir/npm-pack.log):
$(tail -n 5 "$dir/npm-pack.log" 2>/dev/null)"
fi

# Unpack beside the old copy, then swap, so an interrupted run never leaves half a package.
rm -rf "$unpacked.new"
mkdir "$unpacked.new"
tar -xzf "$dir/$tarball" -C "$unpacked.new" --strip-components=1 || fail "cannot unpack $dir/$tarball"
[[ -f "$unpacked.new/modules/processor.mjs" && -f "$unpacked.new/dist/model-en-mixed.bin" ]] ||
  fail "$dir/$tarball has no modules/processor.mjs or dist/model-en-mixed.bin: not the package expected"
rm -rf "$unpacked"
mv "$unpacked.new" "$unpacked"
rm -f "$dir/npm-pack.log"
echo "$unpacked"
