# Sourced by deploy/fuzz.sh and deploy/sanitize.sh (not run): the one clang 14
# ASan + UBSan build in build-fuzz/ that serves both the libFuzzer targets and the
# GoogleTest suites under ASan. LIPSYNC_BUILD_FUZZERS compiles every target with
# -fsanitize=fuzzer-no-link,address,undefined; only the fuzz executables link
# libFuzzer's main (-fsanitize=fuzzer), the tests link gtest's. One build instead
# of a clang build for the fuzzers and a GCC one for the tests: the core and the
# server are compiled once (docs/security.md, "CI timings").
# -O1 -gline-tables-only: reports keep file:line, the build skips full debug
# info (the costliest part of a -g build); no NDEBUG, so assertions stay on.

# build_asan [TARGET...]: configure build-fuzz/ and build those targets (every target with none).
build_asan() {
  if ! command -v clang++-14 >/dev/null 2>&1; then
    echo "asan build: clang++-14 is missing (apt-get install clang-14 libclang-rt-14-dev)" >&2
    exit 1
  fi
  local launcher=()
  if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
  cmake -S . -B build-fuzz -G Ninja -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" "${launcher[@]}" \
    -DLIPSYNC_BUILD_FUZZERS=ON -DLIPSYNC_BUILD_TESTS=ON -DLIPSYNC_BUILD_BENCHMARKS=OFF >/dev/null
  cmake --build build-fuzz -j "$(nproc)" ${1:+--target "$@"}
}
