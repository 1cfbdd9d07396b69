#!/usr/bin/env bash
# install_test.sh BUILD_DIR CXX: installs BUILD_DIR into a fresh temporary prefix, then
#   1. builds tests/install/consumer against it with find_package(lipsync CONFIG),
#   2. builds the same source against it with `pkg-config --cflags --libs lipsync-client`,
#   3. starts the installed lipsyncd on 127.0.0.1:0 and runs both programs against it,
#   4. checks the installed Python client imports from the prefix (no source tree on the path).
# Skips (exit 77) only when cmake or pkg-config is missing.
set -euo pipefail
build=$(cd "$1" && pwd)
cxx=$2
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
source "$here/../support/listening_address.sh"
for tool in cmake pkg-config; do
  command -v "$tool" >/dev/null || { echo "SKIP: $tool is not installed (apt-get install $tool)"; exit 77; }
done
work=$(mktemp -d "${TMPDIR:-/tmp}/lipsync-install.XXXXXX")
server_pid=
cleanup() {
  [[ -n "$server_pid" ]] && kill "$server_pid" 2>/dev/null && wait "$server_pid" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT
prefix=$work/prefix

cmake --install "$build" --prefix "$prefix" >"$work/install.log"
for file in bin/lipsyncd bin/lipsync bin/lipsync-loadtest share/lipsync/data/models/default.json share/doc/lipsyncd/server.md \
            share/lipsync/web/viewer.js share/lipsync/data/face/viewer_face.json \
            etc/lipsyncd/lipsyncd.json lib/systemd/system/lipsyncd.service include/lipsync/client/animation_client.hpp \
            include/lipsync/v1/lipsync.grpc.pb.h lib/cmake/lipsync/lipsyncConfig.cmake \
            lib/pkgconfig/lipsync-client.pc lib/python3/dist-packages/lipsync_client/client.py \
            lib/python3/dist-packages/lipsync/v1/lipsync_pb2_grpc.py; do
  [[ -e "$prefix/$file" ]] || { echo "FAIL: cmake --install left no $file under the prefix"; exit 1; }
done
leaked=$(grep -E '^-- (Installing|Up-to-date): ' "$work/install.log" | grep -v -F -- ": $prefix/" || true)
[[ -z "$leaked" ]] || { echo "FAIL: installed outside the prefix:"; echo "$leaked"; exit 1; }

# 1. find_package
cmake -S "$here/consumer" -B "$work/cmake-build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_CXX_STANDARD=20 -DCMAKE_PREFIX_PATH="$prefix" >"$work/configure.log" \
  || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/cmake-build" >"$work/build.log" 2>&1 || { cat "$work/build.log"; exit 1; }
# 2. pkg-config (the .pc file finds its prefix from its own place)
export PKG_CONFIG_PATH=$prefix/lib/pkgconfig
flags=$(pkg-config --cflags --libs lipsync-client)
# shellcheck disable=SC2086
"$cxx" -std=c++20 -O1 "$here/consumer/consumer.cpp" -o "$work/consumer-pc" $flags

# 3. both against the installed server
"$prefix/bin/lipsyncd" --listen 127.0.0.1:0 --log-level warn >"$work/server.out" 2>"$work/server.err" &
server_pid=$!
address=$(wait_for_listening_address "$work/server.out" 10) ||
  { echo "FAIL: the installed lipsyncd did not start"; cat "$work/server.err"; exit 1; }
for program in "$work/cmake-build/consumer" "$work/consumer-pc"; do
  out=$("$program" "$address") || { echo "FAIL: $program: $out"; exit 1; }
  [[ "$out" =~ ^frames=[1-9][0-9]*\ streamed=[1-9] ]] || { echo "FAIL: $program printed '$out'"; exit 1; }
  echo "$(basename "$program"): $out"
done

# 4. the Python client from the prefix alone
python_out=$(cd "$work" && PYTHONPATH="$prefix/lib/python3/dist-packages" PYTHONNOUSERSITE=1 /usr/bin/python3 -c "
import lipsync_client, sys
from lipsync_client import Client
with Client('$address') as client:
    track = client.render([('M', 0, 80000), ('AA', 80000, 250000)])
    print(lipsync_client.__file__.startswith('$prefix'), len(track.frames) > 0)
")
[[ "$python_out" == "True True" ]] || { echo "FAIL: installed Python client: $python_out"; exit 1; }
echo "PASS: installed under $prefix; find_package, pkg-config and Python consumers ran against the installed lipsyncd"
