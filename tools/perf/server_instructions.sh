#!/usr/bin/env bash
# Server work per frame in instructions: lipsyncd against the bare gRPC server
# (tests/bench/grpc_baseline_server), each run under callgrind and driven by the
# same `lipsync loadtest --fast` workload (fixed seed; MODE=realtime below for
# real-time sessions). Instruction counts do not depend on what else the machine
# is doing, so the ratio is repeatable on a shared 2-core machine where
# wall-clock throughput moves by ±20 %.
#
#   tools/perf/server_instructions.sh [BUILD_DIR]    (default build-perf)
#
# Environment: PRODUCERS=8, DURATION=20 seconds of load, CONNECTIONS=4, SUBSCRIBERS=0 per session,
# MODE=fast (each utterance sent as fast as possible) or realtime (each phoneme in its own message
# when its start time comes, as in the capacity curve; use enough PRODUCERS, e.g. 100, and note
# that callgrind runs a server about 50 times slower, so that it must keep up at that rate)
# (with subscribers, frames counts what producers and subscribers received: a frame sent to a
# producer and two subscribers counts three times).
# What a server spends without load (start-up, model loading, DURATION seconds of
# idling, shutdown) is measured by an idle run of each and subtracted. Prints
# instructions per frame for each server and their ratio.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../../tests/support/listening_address.sh"

BUILD=${1:-build-perf}
PRODUCERS=${PRODUCERS:-8}
DURATION=${DURATION:-20}
CONNECTIONS=${CONNECTIONS:-4}
SUBSCRIBERS=${SUBSCRIBERS:-0}
MODE=${MODE:-fast}
[[ $MODE == fast || $MODE == realtime ]] || { echo "MODE must be fast or realtime, not '$MODE'" >&2; exit 2; }
OUT_DIR=${OUT_DIR:-$(mktemp -d /tmp/server_instructions.XXXXXX)}
mkdir -p "$OUT_DIR"

LIPSYNCD=$BUILD/server/lipsyncd
LIPSYNC=$BUILD/clients/cli/lipsync
BASELINE=$BUILD/tests/bench/grpc_baseline_server
for binary in "$LIPSYNCD" "$LIPSYNC" "$BASELINE"; do
  [[ -x $binary ]] || { echo "missing $binary: build lipsyncd lipsync grpc_baseline_server in $BUILD" >&2; exit 2; }
done
command -v valgrind >/dev/null || { echo "valgrind is needed (apt install valgrind)" >&2; exit 2; }

# measure NAME LOAD(0|1) COMMAND...: total instructions of the server process over
# its whole life, with or without the load; prints "instructions frames".
measure() {
  local name=$1 load=$2; shift 2
  local tag=$OUT_DIR/$name-$load
  valgrind --tool=callgrind --callgrind-out-file="$tag.callgrind" "$@" --listen 127.0.0.1:0 \
    >"$tag.out" 2>"$tag.err" &
  local pid=$!
  local addr
  addr=$(wait_for_listening_address "$tag.out" 30) ||
    { echo "$name did not start" >&2; cat "$tag.err" >&2; kill "$pid"; exit 1; }
  local frames=0
  if [[ $load == 1 ]]; then
    local extra=()
    [[ $name == baseline ]] && extra=(--no-verify)
    "$LIPSYNC" loadtest --server "$addr" --connections "$CONNECTIONS" "--$MODE" --producers "$PRODUCERS" \
      --duration "$DURATION" --subscribers-per-session "$SUBSCRIBERS" --json "${extra[@]}" >"$tag.json"
    frames=$(python3 -c 'import json,sys; f=json.load(open(sys.argv[1]))["frames"]; print(f["producers"] + f["subscribers"])' \
      "$tag.json")
  else
    sleep "$DURATION"
  fi
  kill -TERM "$pid"
  wait "$pid" || true
  local total
  total=$(grep -m1 "^summary:" "$tag.callgrind" | awk '{print $2}')
  echo "$total $frames"
}

echo "results in $OUT_DIR"
declare -A per_frame
for name in lipsyncd baseline; do
  if [[ $name == lipsyncd ]]; then command=("$LIPSYNCD" --log-level warn); else command=("$BASELINE"); fi
  read -r idle _ < <(measure "$name" 0 "${command[@]}")
  read -r loaded frames < <(measure "$name" 1 "${command[@]}")
  per_frame[$name]=$(python3 -c "print(($loaded - $idle) / $frames)")
  printf '%-9s %14s instructions loaded, %12s idle, %9s frames: %8.0f instructions per frame\n' \
    "$name" "$loaded" "$idle" "$frames" "${per_frame[$name]}"
done
python3 -c "print(f'lipsyncd / baseline instructions per frame: {${per_frame[lipsyncd]} / ${per_frame[baseline]}:.3f}')"
