#!/usr/bin/env bash
# A client-only build (-DLIPSYNC_CLIENT_ONLY=ON, docs/deploy.md) is the C++ client library and what
# it needs (the core without the face, the generated stubs), and nothing else: it configures without
# looking for CLI11, espeak-ng or PocketSphinx (the command line's and the server's dependencies),
# and its build has no lipsync, lipsyncd, face, options or speech target. Configure only: seconds.
#   client_only_test.sh SOURCE_DIR
set -euo pipefail
source_dir=$1
build=$(mktemp -d)
trap 'rm -rf "$build"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

cmake -S "$source_dir" -B "$build" -G Ninja -DLIPSYNC_CLIENT_ONLY=ON >"$build/configure.log" 2>&1 ||
  { cat "$build/configure.log" >&2; fail "the client-only build does not configure"; }
targets=$(ninja -C "$build" -t targets all | sed -n 's/^\([A-Za-z0-9_.-]*\): phony$/\1/p')
for wanted in lipsync_client lipsync_proto lipsync_core; do
  grep -qx "$wanted" <<<"$targets" || fail "no target $wanted in the client-only build"
done
for unwanted in lipsync lipsyncd lipsync-loadtest lipsync_server lipsync_face lipsync_options lipsync_speech; do
  if grep -qx "$unwanted" <<<"$targets"; then fail "the client-only build has the target $unwanted"; fi
done
if grep -qiE '^(CLI11_DIR|pkgcfg_lib_ESPEAK|pkgcfg_lib_POCKETSPHINX)' "$build/CMakeCache.txt"; then
  fail "the client-only build looked for the CLI's or the server's dependencies: $(grep -iE '^(CLI11_DIR|pkgcfg_lib_ESPEAK|pkgcfg_lib_POCKETSPHINX)' "$build/CMakeCache.txt")"
fi
echo "client-only build: $(wc -w <<<"$targets") phony targets, the client library and what it needs"
