#!/usr/bin/env bash
# Live voices per core: lipsyncd pinned to one core (SERVER_CPUS, default 0; --listen-threads
# LISTEN_THREADS, default 1), `lipsync loadtest --listen` on another (CLIENT_CPUS, default 1), at
# each count of STREAMS live voices for DURATION seconds, with and without transcripts
# (docs/performance.md, "Live audio").
#
#   tools/perf/listen_curve.sh [BUILD_DIR]      (default build)
#
# Environment: STREAMS="1 2 4 8 16 32", DURATION=20 seconds per step, MODES="transcript audio"
# (transcript: each sentence's words sent ahead of its audio; audio: recognised from the audio
# alone), LATENCY_MS (unset: the server's 200), LISTEN_THREADS (default 1). A fresh lipsyncd for
# every step, so that one step's backlog does not spill into the next. Prints one markdown table row per step; raw JSON reports go
# to $OUT_DIR (default a temporary folder).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
source "$root/tests/support/listening_address.sh"

BUILD=${1:-build}
STREAMS=${STREAMS:-"1 2 4 8 16 32"}
DURATION=${DURATION:-20}
MODES=${MODES:-"transcript audio"}
SERVER_CPUS=${SERVER_CPUS:-0}
CLIENT_CPUS=${CLIENT_CPUS:-1}
LISTEN_THREADS=${LISTEN_THREADS:-1}
OUT_DIR=${OUT_DIR:-$(mktemp -d)}
mkdir -p "$OUT_DIR"
lipsyncd="$BUILD/server/lipsyncd"
lipsync="$BUILD/clients/cli/lipsync"
for program in "$lipsyncd" "$lipsync"; do
  [[ -x $program ]] || { echo "listen_curve: $program is missing: build first (deploy/build.sh)" >&2; exit 2; }
done
latency=()
[[ -n ${LATENCY_MS:-} ]] && latency=(--latency-ms "$LATENCY_MS")

echo "| mode | streams | whole | latency p50 / p95 / max (ms) | worst stream's p95 (ms) | within budget | server CPU (cores) |"
echo "|---|---:|---:|---|---:|---:|---:|"
for mode in $MODES; do
  for streams in $STREAMS; do
    out="$OUT_DIR/server-$mode-$streams.out"
    taskset -c "$SERVER_CPUS" "$lipsyncd" --listen 127.0.0.1:0 --listen-threads "$LISTEN_THREADS" --log-level warn >"$out" 2>&1 &
    server=$!
    address=$(wait_for_listening_address "$out" 10 "$server") || { echo "listen_curve: lipsyncd did not start" >&2; exit 1; }
    before=$(awk '{print $14 + $15}' "/proc/$server/stat")
    transcript=()
    [[ $mode == transcript ]] && transcript=(--transcript)
    report="$OUT_DIR/$mode-$streams.json"
    taskset -c "$CLIENT_CPUS" "$lipsync" loadtest --listen --server "$address" --producers "$streams" \
      --duration "$DURATION" "${transcript[@]}" "${latency[@]}" --json >"$report" || true
    after=$(awk '{print $14 + $15}' "/proc/$server/stat")
    kill "$server"
    wait "$server" || true
    /usr/bin/python3 - "$report" "$mode" "$streams" "$before" "$after" "$(getconf CLK_TCK)" <<'PY'
import json, sys
report = json.load(open(sys.argv[1]))
mode, streams, before, after, ticks = sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]), int(sys.argv[6])
latency = report["latency_ms"]
cpu = (after - before) / ticks / report["elapsed_s"]
errors = ", ".join(f"{code} {count}" for code, count in report["errors"].items())
print(f"| {mode} | {streams} | {report['streams_whole']}/{streams}{' (' + errors + ')' if errors else ''} | "
      f"{latency['p50']:.0f} / {latency['p95']:.0f} / {latency['max']:.0f} | {report['worst_stream_p95_ms']:.0f} | "
      f"{report['within_budget_percent']:.1f} % | {cpu:.2f} |")
PY
  done
done
echo "raw reports: $OUT_DIR" >&2
