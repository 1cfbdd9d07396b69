#!/usr/bin/env bash
# The core and its tests need no gRPC (docs/architecture.md, "Building parts of it"): a build with
# the server, the client library and the Python stubs off configures without looking for gRPC or
# Protobuf, has the core's, the formats', the face's, the CLI's and the speech tests and nothing of
# the network, and its core_test builds and passes there.
#   no_grpc_test.sh SOURCE_DIR
set -euo pipefail
source_dir=$1
build=$(mktemp -d)
trap 'rm -rf "$build"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S "$source_dir" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" \
  -DLIPSYNC_BUILD_SERVER=OFF -DLIPSYNC_BUILD_CLIENT=OFF -DLIPSYNC_BUILD_PYTHON=OFF >"$build/configure.log" 2>&1 ||
  { cat "$build/configure.log" >&2; fail "the build without gRPC does not configure"; }
targets=$(ninja -C "$build" -t targets all | sed -n 's/^\([A-Za-z0-9_.-]*\): phony$/\1/p')
for wanted in lipsync_core lipsync_face lipsync core_test formats_test output_test face_test cli_test speech_test; do
  grep -qx "$wanted" <<<"$targets" || fail "no target $wanted in the build without gRPC"
done
for unwanted in lipsyncd lipsync_server lipsync_client lipsync_proto server_test network_cli_test; do
  if grep -qx "$unwanted" <<<"$targets"; then fail "the build without gRPC has the target $unwanted"; fi
done
if grep -qE '^(gRPC_DIR|Protobuf_INCLUDE_DIR|Protobuf_LIBRARY)[:=]' "$build/CMakeCache.txt"; then
  fail "the build without gRPC looked for gRPC or Protobuf: $(grep -E '^(gRPC_DIR|Protobuf_)' "$build/CMakeCache.txt" | head -3)"
fi
ninja -C "$build" core_test >"$build/build.log" 2>&1 || { tail -40 "$build/build.log" >&2; fail "core_test does not build without gRPC"; }
"$build/tests/core/core_test" --gtest_brief=1 >"$build/run.log" 2>&1 || { tail -40 "$build/run.log" >&2; fail "core_test fails in the build without gRPC"; }
echo "build without gRPC: $(wc -w <<<"$targets") phony targets, no network ones; core_test: $(grep -c . "$build/run.log") lines, passed"
