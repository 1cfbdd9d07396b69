#!/usr/bin/env bash
# Installs the Debian 12 packages that lipsyncd's build and tests need, only
# those that are missing (apt-get update runs only when something is missing).
# Run as root, or as a user with sudo.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

packages=(
  # build
  build-essential cmake ninja-build
  # libraries
  nlohmann-json3-dev libeigen3-dev libspdlog-dev libboost-dev
  # the command lines of lipsyncd and lipsync (core/options/)
  libcli11-dev
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  # the load generator's own HTTP/2 client (tools/loadtest/h2_grpc_connection.cpp)
  libnghttp2-dev
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  # deploy/fuzz.sh (CI): clang 14 and its libFuzzer + sanitizer runtimes
  clang-14 libclang-rt-14-dev
  # deploy/style.sh (CI): the C++ layout and lint checks
  clang-format-14 clang-tidy-14
  # TTS front-ends used by the examples and tests (phoneme timings)
  flite festival festvox-kallpc16k
  # the Python client's Listen example pipes the espeak-ng program's audio (espeak-ng --stdout)
  espeak-ng
  # lipsync::speech: `lipsync say` (espeak-ng) and `lipsync align` (PocketSphinx and its en-us model)
  libespeak-ng-dev espeak-ng-data libpocketsphinx-dev libsphinxbase-dev pocketsphinx-en-us
  # recorded human speech with transcripts for the speech tests (LibriVox sentences)
  pocketsphinx-testdata
  # `lipsync render --video/--still` pipes frames to ffmpeg; the CLI tests check with ffprobe
  ffmpeg
  # the Python client (run with /usr/bin/python3), its pip package test (venv) and the manifest test
  python3 python3-grpcio python3-protobuf python3-venv python3-pip python3-yaml
  # the install test (pkg-config consumer) and the multi-replica test (nginx as the balancer)
  pkg-config nginx
  # TLS and API keys: libcrypto (lipsyncd checks its TLS files and hashes API keys with SHA-256);
  # the openssl command makes the test certificates (tests/support/make_test_certs.sh)
  libssl-dev openssl
  # the browser viewer's test: headless Chromium (WebGL through SwiftShader) driven over the
  # DevTools protocol from /usr/bin/python3 with websocket-client
  chromium python3-websocket
  # the Blender add-on's tests (tests/integrations/blender): Blender headless; numpy for its glTF exporter
  blender python3-numpy
  # the Godot add-on's test (clients/godot, tests/integrations/godot): Godot 3's headless runtime
  godot3-server
)
# npm fetches the Khronos glTF validator for the Blender add-on's test (a Node.js that brings its
# own npm, such as NodeSource's, conflicts with Debian's npm package: then it is not asked for)
command -v npm >/dev/null 2>&1 || packages+=(npm)

missing=()
for package in "${packages[@]}"; do
  status="$(dpkg-query -W -f='${Status}' "$package" 2>/dev/null || true)"
  if [[ "$status" != "install ok installed" ]]; then
    missing+=("$package")
  fi
done

if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install-deps: all ${#packages[@]} packages are installed"
  exit 0
fi

if [[ "$(id -u)" -eq 0 ]]; then
  sudo=()
elif command -v sudo >/dev/null 2>&1; then
  sudo=(sudo)
else
  echo "install-deps: missing packages: ${missing[*]}" >&2
  echo "install-deps: run this script as root (or install sudo) to install them" >&2
  exit 1
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${sudo[@]}" apt-get update
"${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends "${missing[@]}"
echo "install-deps: installed ${#missing[@]} package(s)"
