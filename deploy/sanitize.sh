#!/usr/bin/env bash
# Builds and runs test suites under GCC's sanitizers (docs/security.md).
#   deploy/sanitize.sh asan [TEST...]  ASan + UBSan build in build-asan/, runs the given
#                                      test executables (default: core_test formats_test;
#                                      "all" builds and runs every test)
#   deploy/sanitize.sh tsan            TSan build in build-tsan/ of the server tests
#                                      (server_test server_limits_test face_workers_test)
# Any sanitizer report fails the test it comes from (halt_on_error / exitcode), and
# ctest's status is the script's. Times each phase.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

usage() { echo "usage: deploy/sanitize.sh asan [TEST...|all] | tsan" >&2; exit 2; }
[[ $# -ge 1 ]] || usage
mode="$1"
shift
launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi

# configure_build DIR FLAGS TARGETS...: a RelWithDebInfo build (-O1 keeps the traces readable).
configure_build() {
  local dir="$1" flags="$2"
  shift 2
  local start=$SECONDS
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g" \
    -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="$flags" -DCMAKE_SHARED_LINKER_FLAGS="$flags" \
    -DLIPSYNC_BUILD_BENCHMARKS=OFF "${launcher[@]}" >/dev/null
  cmake --build "$dir" -j "$(nproc)" ${1:+--target "$@"}
  echo "sanitize: $dir built in $((SECONDS - start)) s"
}

# run_tests DIR TEST...: ctest over the tests of those executables (all tests with none named).
run_tests() {
  local dir="$1"
  shift
  local start=$SECONDS
  local filter=()
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
    flags="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
    if [[ "${tests[*]}" == all ]]; then
      echo "sanitize: ASan + UBSan, every test"
      configure_build build-asan "$flags"
      run_tests build-asan
    else
      echo "sanitize: ASan + UBSan, ${tests[*]}"
      configure_build build-asan "$flags" "${tests[@]}"
      run_tests build-asan "${tests[@]}"
    fi
    ;;
  tsan)
    [[ $# -eq 0 ]] || usage
    tests=(server_test server_limits_test face_workers_test)
    export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1"
    echo "sanitize: TSan, ${tests[*]}"
    configure_build build-tsan "-fsanitize=thread -fno-omit-frame-pointer" "${tests[@]}" lipsyncd
    run_tests build-tsan "${tests[@]}"
    ;;
  *) usage ;;
esac
