#!/usr/bin/env bash
# Builds and runs test suites under sanitizers (docs/security.md, "Sanitizers").
#   deploy/sanitize.sh asan [TEST...|all]  clang 14 ASan + UBSan, in build-fuzz/ (the build the
#                                          fuzzers share, deploy/asan-build.sh); runs the given
#                                          test executables (default: core_test formats_test;
#                                          "all": every test but those labelled soak)
#   deploy/sanitize.sh tsan [TEST...]      clang 14 TSan in build-tsan-clang/ of the server tests
#                                          (default: tsan_tests below, as CI runs them), then the
#                                          canary that must be reported (tests/server/tsan_canary.cpp).
#                                          gRPC's half is made invisible or stated: deploy/sanitizers/tsan.ignorelist,
#                                          tsan.exports, tsan_edges.cpp (preloaded), tsan.supp
#                                          (docs/security.md, "Sanitizers"). TSAN_EXTRA replaces
#                                          halt_on_error=1 in TSAN_OPTIONS, e.g.
#                                          TSAN_EXTRA=halt_on_error=0:log_path=/tmp/tsan/r to read every report.
# Any sanitizer report fails the test it comes from (halt_on_error / exitcode), and
# ctest's status is the script's. Times each phase.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

usage() { echo "usage: deploy/sanitize.sh asan [TEST...|all] | tsan [TEST...]" >&2; exit 2; }
[[ $# -ge 1 ]] || usage
mode="$1"
shift
# The server tests that start threads of our own (face workers, outboxes, sessions, drain):
# what TSan is for. Every one links the server; each more costs its own compile only (those
# that start lipsyncd as a child build its TSan binary through their dependency on it).
tsan_tests=(server_test server_limits_test face_workers_test outbox_test server_shutdown_test tenants_test
            session_routing_test listen_test)

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
    export LSAN_OPTIONS="suppressions=$PWD/deploy/sanitizers/lsan.supp:print_suppressions=0"
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
    # Clang 14 TSan (its ignore lists; GCC 12 has none). Debian's gRPC, protobuf and abseil are
    # not instrumented; what of them is compiled into our executables is left uninstrumented
    # too (deploy/sanitizers/tsan.ignorelist), their calls keep to libstdc++.so's own string code
    # (deploy/sanitizers/tsan.exports), the synchronisation TSan cannot see is stated (the preloaded
    # deploy/sanitizers/tsan_edges.cpp, and the reactors' HandoffReactor), and their interceptor calls
    # are ignored (deploy/sanitizers/tsan.supp, ignore_noninstrumented_modules). Every line of server/,
    # clients/, core/ and tests/ stays instrumented (docs/security.md, "Sanitizers").
    tests=("$@")
    [[ ${#tests[@]} -gt 0 ]] || tests=("${tsan_tests[@]}")
    launcher=()
    if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
    start=$SECONDS
    # Neither ninja nor ccache 4.7 looks at the contents of the ignore list or the exports
    # script: their hash joins the flags, so an edit rebuilds every object, and ccache hashes
    # the list with each compilation.
    ignorelist_hash="$(cat deploy/sanitizers/tsan.ignorelist deploy/sanitizers/tsan.exports | sha256sum | cut -c1-16)"
    export CCACHE_EXTRAFILES="$PWD/deploy/sanitizers/tsan.ignorelist"
    cmake -S . -B build-tsan-clang -G Ninja -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_C_COMPILER=clang-14 \
      -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
      -DCMAKE_CXX_FLAGS="-fsanitize=thread -fno-omit-frame-pointer -fsanitize-ignorelist=$PWD/deploy/sanitizers/tsan.ignorelist -DLIPSYNC_TSAN_IGNORELIST=$ignorelist_hash" \
      -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=thread -Wl,--version-script=$PWD/deploy/sanitizers/tsan.exports" \
      -DCMAKE_SHARED_LINKER_FLAGS=-fsanitize=thread -DLIPSYNC_BUILD_BENCHMARKS=OFF "${launcher[@]}" >/dev/null
    cmake --build build-tsan-clang -j "$(nproc)" --target "${tests[@]}" tsan_canary
    g++ -std=c++17 -O1 -shared -fPIC -o build-tsan-clang/libtsan_edges.so deploy/sanitizers/tsan_edges.cpp -ldl
    echo "sanitize: build-tsan-clang built in $((SECONDS - start)) s"
    export TSAN_OPTIONS="${TSAN_EXTRA:-halt_on_error=1}:second_deadlock_stack=1:ignore_noninstrumented_modules=1:suppressions=$PWD/deploy/sanitizers/tsan.supp"
    export LD_PRELOAD="$PWD/build-tsan-clang/libtsan_edges.so"
    run_tests build-tsan-clang "${tests[@]}"
    # The canary (tests/server/tsan_canary.cpp): a race planted in a reaction, under the same
    # ignore list, edges, exports and suppressions, must be reported, naming the reaction.
    canary_log="build-tsan-clang/tsan_canary.log"
    if build-tsan-clang/tests/server/tsan_canary >"$canary_log" 2>&1; then
      echo "sanitize: the TSan canary's planted race was not reported ($canary_log)" >&2
      exit 1
    fi
    if ! grep -q "WARNING: ThreadSanitizer: data race" "$canary_log" ||
       ! grep -q "CanaryReactor::OnWriteDone" "$canary_log"; then
      echo "sanitize: the TSan canary failed without a report naming its reaction ($canary_log):" >&2
      cat "$canary_log" >&2
      exit 1
    fi
    echo "sanitize: the TSan canary's planted race was reported, naming CanaryReactor::OnWriteDone"
    ;;
  *) usage ;;
esac
