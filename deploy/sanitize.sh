#!/usr/bin/env bash
# Builds and runs test suites under sanitizers (docs/security.md, "Sanitizers").
#   deploy/sanitize.sh asan [TEST...|all]  clang 14 ASan + UBSan, in build-fuzz/ (the build the
#                                          fuzzers share, deploy/asan-build.sh); runs the given
#                                          test executables (default: core_test formats_test;
#                                          "all": every test but those labelled soak)
#   deploy/sanitize.sh tsan [TEST...]      GCC 12 TSan in build-tsan/ of the server tests (default:
#                                          the threaded ones, tsan_tests below; CI runs
#                                          face_workers_test, the one clean today: docs/security.md),
#                                          suppressions for the uninstrumented gRPC in deploy/tsan.supp
#   deploy/sanitize.sh tsan-clang [TEST...] clang 14 TSan in build-tsan-clang/ with deploy/tsan.ignorelist
#                                          and the abseil Mutex probe preloaded: 15 reports left in 59
#                                          server tests (docs/security.md); not a CI step yet
# Any sanitizer report fails the test it comes from (halt_on_error / exitcode), and
# ctest's status is the script's. Times each phase.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

usage() { echo "usage: deploy/sanitize.sh asan [TEST...|all] | tsan [TEST...] | tsan-clang [TEST...]" >&2; exit 2; }
[[ $# -ge 1 ]] || usage
mode="$1"
shift
# The server tests that start threads of our own (face workers, outboxes, sessions, drain):
# what TSan is for. Every one links the server; each more costs its own compile only (those
# that start lipsyncd as a child build its TSan binary through their dependency on it).
tsan_tests=(server_test server_limits_test face_workers_test server_shutdown_test tenants_test
            session_routing_test)

# run_tests DIR TEST...: ctest over the tests of those executables (with none named, all tests but
# the soak, whose RSS judge ASan's quarantine and shadow memory defeat, and those labelled no_asan,
# each with its reason in its CMakeLists and docs/security.md).
run_tests() {
  local dir="$1"
  shift
  local start=$SECONDS
  local filter=(-LE '^(soak|no_asan)$')
  if [[ $# -gt 0 ]]; then
    local regex
    regex="$(printf '%s\\.|' "$@")"
    filter=(-R "^(${regex%|})")
  fi
  ctest --test-dir "$dir" --output-on-failure -j "$(nproc)" "${filter[@]}"
  echo "sanitize: $dir tests ran in $((SECONDS - start)) s"
}

case "$mode" in
  asan)
    tests=("$@")
    [[ ${#tests[@]} -gt 0 ]] || tests=(core_test formats_test)
    export ASAN_OPTIONS="halt_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1"
    export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
    # Leaks inside Debian's libraries; print_suppressions=0 keeps the CLI tests' stderr theirs.
    export LSAN_OPTIONS="suppressions=$PWD/deploy/lsan.supp:print_suppressions=0"
    source deploy/asan-build.sh
    start=$SECONDS
    if [[ "${tests[*]}" == all ]]; then
      echo "sanitize: ASan + UBSan, every test"
      build_asan
      echo "sanitize: build-fuzz built in $((SECONDS - start)) s"
      run_tests build-fuzz
    else
      echo "sanitize: ASan + UBSan, ${tests[*]}"
      build_asan "${tests[@]}"
      echo "sanitize: build-fuzz built in $((SECONDS - start)) s"
      run_tests build-fuzz "${tests[@]}"
    fi
    ;;
  tsan)
    tests=("$@")
    [[ ${#tests[@]} -gt 0 ]] || tests=("${tsan_tests[@]}")
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/deploy/tsan.supp"
    echo "sanitize: TSan, ${tests[*]}"
    launcher=()
    if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
    start=$SECONDS
    # -O1 -g1: line tables for the reports, no full debug info.
    cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
      -DCMAKE_CXX_FLAGS="-fsanitize=thread -fno-omit-frame-pointer" -DCMAKE_EXE_LINKER_FLAGS=-fsanitize=thread \
      -DCMAKE_SHARED_LINKER_FLAGS=-fsanitize=thread -DLIPSYNC_BUILD_BENCHMARKS=OFF "${launcher[@]}" >/dev/null
    cmake --build build-tsan -j "$(nproc)" --target "${tests[@]}"
    echo "sanitize: build-tsan built in $((SECONDS - start)) s"
    run_tests build-tsan "${tests[@]}"
    ;;
  tsan-clang)
    # Clang 14 TSan in build-tsan-clang/ with gRPC's and protobuf's inline code left
    # uninstrumented (deploy/tsan.ignorelist) and abseil's Mutex made visible by the preloaded
    # probe (deploy/tsan_absl_mutex_probe.cpp): the way to a clean TSan run of the server tests
    # (docs/security.md, "Where TSan stands"). Not a CI step yet.
    tests=("$@")
    [[ ${#tests[@]} -gt 0 ]] || tests=("${tsan_tests[@]}")
    launcher=()
    if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
    start=$SECONDS
    cmake -S . -B build-tsan-clang -G Ninja -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_C_COMPILER=clang-14 \
      -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
      -DCMAKE_CXX_FLAGS="-fsanitize=thread -fno-omit-frame-pointer -fsanitize-ignorelist=$PWD/deploy/tsan.ignorelist" \
      -DCMAKE_EXE_LINKER_FLAGS=-fsanitize=thread -DCMAKE_SHARED_LINKER_FLAGS=-fsanitize=thread \
      -DLIPSYNC_BUILD_BENCHMARKS=OFF "${launcher[@]}" >/dev/null
    cmake --build build-tsan-clang -j "$(nproc)" --target "${tests[@]}"
    g++ -std=c++17 -O1 -shared -fPIC -o build-tsan-clang/libabsl_mutex_tsan.so deploy/tsan_absl_mutex_probe.cpp -ldl
    echo "sanitize: build-tsan-clang built in $((SECONDS - start)) s"
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$PWD/deploy/tsan.supp"
    export LD_PRELOAD="$PWD/build-tsan-clang/libabsl_mutex_tsan.so"
    run_tests build-tsan-clang "${tests[@]}"
    ;;
  *) usage ;;
esac
