#!/usr/bin/env bash
# Server load test: lipsyncd against a bare gRPC server sending the same messages
# (tests/bench/grpc_baseline_server), both on 127.0.0.1, driven by `lipsync loadtest`.
#
#   tools/perf/server_loadtest.sh [BUILD_DIR]      (default build-perf; Release, benchmarks on)
#
# Environment (all bounded): SESSIONS="100 200 500 1000 2000" real-time sessions per step,
# DURATION=10 seconds per step, REPEAT=3 rounds, SUBSCRIBERS="0 1 3" subscribers per session (each
# step is run with each count, against lipsyncd and against the baseline, whose fan-out mode sends
# the same bytes to every subscriber of a session), FAST_PRODUCERS=50
# producers for the fast-mode throughput runs, CONNECTIONS=8 HTTP/2 connections, CLIENT=h2 (the
# generator's own HTTP/2 client; grpc: gRPC's C++ client library, which costs the generator about
# twice the CPU, docs/performance.md "The load generator"), SERVER_CPUS and
# CLIENT_CPUS (taskset CPU lists, e.g. 0 and 1: the servers on one core, the load generator on the
# other; unset: no pinning), MESH_SESSIONS="500" real-time sessions of which a share MESH_SHARE=0.01
# ask for the physics face (level MESH_LEVEL=1; lipsyncd only). SESSIONS, MESH_SESSIONS and
# FAST_PRODUCERS set to "" leave those runs out (e.g. FAST_PRODUCERS=50 SESSIONS="" MESH_SESSIONS=""
# for fast mode alone). BASELINE_BUSY_NS=0 nanoseconds of work the baseline adds per frame it
# releases (its --busy-ns-per-frame; docs/performance.md "What fast mode's gap is made of"), 0 to
# 1000000.
# Each round runs every step against lipsyncd and the baseline back to back (alternating which goes
# first), so that ratios compare runs made under the same machine load. Prints one table row per
# run and a summary of medians; raw JSON reports go to $OUT_DIR (default a temporary folder).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../../tests/support/listening_address.sh"

BUILD=${1:-build-perf}
SESSIONS=${SESSIONS-"100 200 500 1000 2000"}
SUBSCRIBERS=${SUBSCRIBERS:-"0 1 3"}
DURATION=${DURATION:-10}
REPEAT=${REPEAT:-3}
FAST_PRODUCERS=${FAST_PRODUCERS-50}
MESH_SESSIONS=${MESH_SESSIONS-"500"}
MESH_SHARE=${MESH_SHARE:-0.01}
MESH_LEVEL=${MESH_LEVEL:-1}
CONNECTIONS=${CONNECTIONS:-8}
CLIENT=${CLIENT:-h2}
BASELINE_BUSY_NS=${BASELINE_BUSY_NS:-0}
OUT_DIR=${OUT_DIR:-$(mktemp -d /tmp/server_loadtest.XXXXXX)}
mkdir -p "$OUT_DIR"
# The summary reads every run report in OUT_DIR: an earlier run's must not join this one's.
if compgen -G "$OUT_DIR/r[0-9]*-*" >/dev/null; then
  echo "removing the run reports of an earlier load test from $OUT_DIR" >&2
  rm -f "$OUT_DIR"/r[0-9]*-*
fi
SERVER_PIN=()
CLIENT_PIN=()
[[ -n ${SERVER_CPUS:-} ]] && SERVER_PIN=(taskset -c "$SERVER_CPUS")
[[ -n ${CLIENT_CPUS:-} ]] && CLIENT_PIN=(taskset -c "$CLIENT_CPUS")

LIPSYNCD=$BUILD/server/lipsyncd
LIPSYNC=$BUILD/clients/cli/lipsync
BASELINE=$BUILD/tests/bench/grpc_baseline_server
for binary in "$LIPSYNCD" "$LIPSYNC" "$BASELINE"; do
  [[ -x $binary ]] || { echo "missing $binary: build lipsyncd lipsync grpc_baseline_server in $BUILD" >&2; exit 2; }
done

PIDS=()
cleanup() { for pid in "${PIDS[@]}"; do kill "$pid" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT INT TERM

# start NAME COMMAND...: starts a server on 127.0.0.1:0, sets ADDR_<NAME> and PID_<NAME>.
start() {
  local name=$1; shift
  local log=$OUT_DIR/$name.out
  "$@" >"$log" 2>"$OUT_DIR/$name.err" &
  local pid=$!
  PIDS+=("$pid")
  local addr
  addr=$(wait_for_listening_address "$log" 10 "$pid") ||
    { echo "$name did not start: $*" >&2; cat "$OUT_DIR/$name.err" >&2; exit 1; }
  printf -v "ADDR_$name" %s "$addr"
  printf -v "PID_$name" %s "$pid"
}

start lipsyncd "${SERVER_PIN[@]}" "$LIPSYNCD" --listen 127.0.0.1:0 --log-level warn
start baseline "${SERVER_PIN[@]}" "$BASELINE" --listen 127.0.0.1:0 --busy-ns-per-frame "$BASELINE_BUSY_NS"
echo "lipsyncd $ADDR_lipsyncd (pid $PID_lipsyncd), baseline $ADDR_baseline (pid $PID_baseline," \
  "$BASELINE_BUSY_NS ns of added work per frame), $(nproc) cores," \
  "servers on CPUs ${SERVER_CPUS:-any}, load generator on CPUs ${CLIENT_CPUS:-any}"
echo "results in $OUT_DIR; load generator: lipsync loadtest --client $CLIENT"

cpu_ticks() { awk '{print $14 + $15}' "/proc/$1/stat"; }
TICK=$(getconf CLK_TCK)

# one NAME TAG ARGS...: one loadtest run against server NAME; writes $OUT_DIR/TAG.json with the
# server's and the client's CPU (cores busy on average) added.
one() {
  local name=$1 tag=$2; shift 2
  local addr_var=ADDR_$name pid_var=PID_$name
  local extra=()
  [[ $name == baseline ]] && extra=(--no-verify)
  local before after start_ns end_ns client_cpu
  before=$(cpu_ticks "${!pid_var}")
  start_ns=$(date +%s%N)
  local TIMEFORMAT='%U %S'
  { time "${CLIENT_PIN[@]}" "$LIPSYNC" loadtest --server "${!addr_var}" --client "$CLIENT" --connections "$CONNECTIONS" --json "${extra[@]}" "$@" \
      >"$OUT_DIR/$tag.raw" 2>"$OUT_DIR/$tag.stderr" || true; } 2>"$OUT_DIR/$tag.time"
  end_ns=$(date +%s%N)
  after=$(cpu_ticks "${!pid_var}")
  python3 - "$OUT_DIR/$tag" "$name" "$before" "$after" "$start_ns" "$end_ns" "$TICK" "$(uptime | sed 's/.*load average: //')" <<'PY'
import json, sys
base, name, before, after, t0, t1, tick, load = sys.argv[1:]
wall = (int(t1) - int(t0)) / 1e9
try:
    report = json.load(open(base + ".raw"))
except Exception as error:
    report = {"failed": str(error)}
user, system = (float(x) for x in open(base + ".time").read().split()[-2:])
report.update(target=name, wall_s=wall, server_cpu=(int(after) - int(before)) / int(tick) / wall,
              client_cpu=(user + system) / wall, load=load)
json.dump(report, open(base + ".json", "w"), indent=1)
PY
}

for round in $(seq "$REPEAT"); do
  if (( round % 2 )); then order=(lipsyncd baseline); else order=(baseline lipsyncd); fi
  for m in $SUBSCRIBERS; do
    for n in $SESSIONS; do
      for name in "${order[@]}"; do
        one "$name" "r$round-realtime${m}sub-$n-$name" --realtime --producers "$n" --subscribers-per-session "$m" \
          --duration "$DURATION"
      done
    done
  done
  for n in $MESH_SESSIONS; do
    one lipsyncd "r$round-mesh-$n-lipsyncd" --realtime --producers "$n" --mesh-share "$MESH_SHARE" \
      --mesh-subdivision "$MESH_LEVEL" --duration "$DURATION"
  done
  for p in $FAST_PRODUCERS; do
    for name in "${order[@]}"; do
      one "$name" "r$round-fast-$p-$name" --fast --producers "$p" --duration "$DURATION"
    done
  done
done

python3 - "$OUT_DIR" <<'PY'
import glob, json, os, statistics, sys
out = sys.argv[1]
runs = []
for path in sorted(glob.glob(os.path.join(out, "r*-*.json"))):
    tag = os.path.basename(path)[:-5]
    rnd, mode, n, name = tag.split("-")
    runs.append(dict(json.load(open(path)), round=int(rnd[1:]), mode=mode, n=int(n), name=name))
print()
print("| round | mode | sessions | server | p50 ms | p95 ms | p99 ms | max ms | subscribers p99 ms | errors | frames/s | server CPU | client CPU | generator CPU (own) | load avg |")
print("|---:|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|")
key = lambda r: (r["mode"], r["n"], r["name"], r["round"])
for r in sorted(runs, key=key):
    if "failed" in r:
        print(f"| {r['round']} | {r['mode']} | {r['n']} | {r['name']} | failed: {r['failed']} |")
        continue
    lat = r["latency_ms"]["producers"]
    errors = sum(r["errors"].values())
    sub = r["latency_ms"]["subscribers"]["p99"] if r.get("subscribers_per_session") else float("nan")
    print(f"| {r['round']} | {r['mode']} | {r['n']} | {r['name']} | {lat['p50']:.2f} | {lat['p95']:.2f} | "
          f"{lat['p99']:.2f} | {lat['max']:.1f} | {sub:.2f} | {errors} | {r['frames']['per_second']:.0f} | "
          f"{r['server_cpu']:.2f} | {r['client_cpu']:.2f} | {r.get('generator_cpu_cores', float('nan')):.2f} | "
          f"{r['load']} |")
print()
print("Medians over rounds:")
print("| mode | sessions | server | p50 ms | p99 ms | errors (sum) | frames/s | server CPU | ratio lipsyncd/baseline (frames/s, same round) |")
print("|---|---:|---|---:|---:|---:|---:|---:|---:|")
groups = {}
for r in runs:
    if "failed" not in r:
        groups.setdefault((r["mode"], r["n"], r["name"]), []).append(r)
for (mode, n, name), rs in sorted(groups.items()):
    med = lambda f: statistics.median(f(r) for r in rs)
    ratio = ""
    if name == "lipsyncd" and (mode, n, "baseline") in groups:
        base = {r["round"]: r["frames"]["per_second"] for r in groups[(mode, n, "baseline")]}
        ratios = [r["frames"]["per_second"] / base[r["round"]] for r in rs if base.get(r["round"])]
        if ratios:
            ratio = f"{statistics.median(ratios):.3f} (" + ", ".join(f"{x:.3f}" for x in ratios) + ")"
    print(f"| {mode} | {n} | {name} | {med(lambda r: r['latency_ms']['producers']['p50']):.2f} | "
          f"{med(lambda r: r['latency_ms']['producers']['p99']):.2f} | "
          f"{sum(sum(r['errors'].values()) for r in rs)} | {med(lambda r: r['frames']['per_second']):.0f} | "
          f"{med(lambda r: r['server_cpu']):.2f} | {ratio} |")
print()
print("Capacity curve: largest session count whose median p99 (producers, and subscribers when there are any)")
print("is under 5 ms, and the medians of the p99s at each step (producers / subscribers, ms):")
print("| mode | server | capacity (sessions) | p99 by step |")
print("|---|---|---:|---|")
for mode in sorted({r["mode"] for r in runs if r["mode"].startswith("realtime")}):
    for name in ("lipsyncd", "baseline"):
        steps = sorted(n for (m, n, s) in groups if m == mode and s == name)
        capacity, cells = 0, []
        for n in steps:
            rs = groups[(mode, n, name)]
            prod = statistics.median(r["latency_ms"]["producers"]["p99"] for r in rs)
            subs = [r["latency_ms"]["subscribers"]["p99"] for r in rs if r.get("subscribers_per_session")]
            sub = statistics.median(subs) if subs else None
            worst = max(prod, sub) if sub is not None else prod
            if worst < 5.0 and all(c[1] for c in cells):
                capacity = n
            cells.append((f"{n}: {prod:.2f}" + (f" / {sub:.2f}" if sub is not None else ""), worst < 5.0))
        print(f"| {mode} | {name} | {capacity} | " + ", ".join(c[0] for c in cells) + " |")
mesh_runs = [r for r in runs if "by_output" in r and r["by_output"].get("mesh", {}).get("producers")]
if mesh_runs:
    print()
    print("With the face on for a share of the sessions (producers' latency, computable -> arrival):")
    print("| round | sessions | with face | no-face p50 ms | no-face p99 ms | face p50 ms | face p99 ms | face frames/s | errors | server CPU |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in sorted(mesh_runs, key=key):
        plain, face = r["by_output"]["no_mesh"], r["by_output"]["mesh"]
        print(f"| {r['round']} | {r['n']} | {face['producers']} | {plain['latency_ms']['producers']['p50']:.2f} | "
              f"{plain['latency_ms']['producers']['p99']:.2f} | {face['latency_ms']['producers']['p50']:.2f} | "
              f"{face['latency_ms']['producers']['p99']:.2f} | {face['frames']['per_second']:.0f} | "
              f"{sum(r['errors'].values())} | {r['server_cpu']:.2f} |")
PY
