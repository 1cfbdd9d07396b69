#!/usr/bin/env bash
# The load generator is a program of its own (tools/loadtest/): the user's lipsync links no
# HTTP/2 client of ours (nghttp2), lipsync-loadtest does, and `lipsync loadtest` runs it; a
# lipsync without the generator beside it says which file is missing and how to get it.
#   loadtest_program_test.sh LIPSYNC LIPSYNC_LOADTEST
set -euo pipefail
lipsync=$1
generator=$2
fail() { echo "FAIL: $*" >&2; exit 1; }

readelf -d "$generator" | grep -q 'NEEDED.*libnghttp2' || fail "$generator does not link nghttp2: is it the generator?"
if readelf -d "$lipsync" | grep -q 'NEEDED.*libnghttp2'; then fail "$lipsync links nghttp2"; fi

help=$("$lipsync" loadtest --help)
[[ $help == "Usage: lipsync loadtest"* ]] || fail "lipsync loadtest --help: $help"
[[ $("$generator" --help) == "$help" ]] || fail "the generator's own help differs from lipsync loadtest's"

set +e
"$lipsync" loadtest --producers 0 2>"${TMPDIR:-/tmp}/loadtest_err.$$"
status=$?
set -e
err=$(cat "${TMPDIR:-/tmp}/loadtest_err.$$"); rm -f "${TMPDIR:-/tmp}/loadtest_err.$$"
[[ $status == 2 && $err == *"--producers"* ]] || fail "a bad option through lipsync loadtest: status $status, '$err'"

alone=$(mktemp -d)
trap 'rm -rf "$alone"' EXIT
cp "$lipsync" "$alone/lipsync"
set +e
err=$("$alone/lipsync" loadtest --help 2>&1 >/dev/null)
status=$?
set -e
[[ $status == 1 ]] || fail "lipsync without the generator: status $status, want 1"
[[ $err == *"$alone/lipsync-loadtest"*"lipsync-loadtest"* ]] || fail "lipsync without the generator said: $err"
echo "loadtest program: ok"
