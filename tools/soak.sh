#!/usr/bin/env bash
# Soak: runs lipsyncd for DURATION seconds under mixed load (tools/soak/soak_load.py:
# streams, followers, subscribers that stall, cancellations, bad and oversize requests,
# face streams, Render) and checks that resident memory and open file descriptors
# stay flat after warm-up (the first quarter of the run, at least 20 s): the samples
# after warm-up are split in two halves, and the largest of the second half may exceed
# the largest of the first by at most SOAK_RSS_SLACK_MB (default 24 MB) and SOAK_FD_SLACK
# fds (default 16): memory that goes up and down with the load passes, memory that keeps
# growing does not. Then SIGTERM: exit 0 expected.
#
#   tools/soak.sh DURATION [BUILD_DIR]      e.g. tools/soak.sh 1800 build
#
# Prints a sample every 10 s and a summary line; exit status 1 on growth, a call
# with a status it should not get, or a bad exit. Needs Debian's /usr/bin/python3
# with python3-grpcio and the stubs the build generates (clients/python/generated).
set -euo pipefail

duration=${1:?usage: tools/soak.sh DURATION_SECONDS [BUILD_DIR]}
build=${2:-build}
here=$(cd "$(dirname "$0")" && pwd)
rss_slack_mb=${SOAK_RSS_SLACK_MB:-24}
fd_slack=${SOAK_FD_SLACK:-16}
work=$(mktemp -d)
trap 'kill "$server" 2>/dev/null || true; kill "$load" 2>/dev/null || true; rm -rf "$work"' EXIT

"$build/server/lipsyncd" --listen 127.0.0.1:0 --metrics-listen 127.0.0.1:0 --log-level warn \
  --subscriber-queue-frames 200 --stalled-subscriber-ms 500 --session-retention-ms 1000 \
  --face-threads 1 >"$work/out" 2>"$work/err" &
server=$!
for _ in $(seq 100); do grep -q "metrics on" "$work/out" && break; sleep 0.1; done
address=$(sed -n 's/^lipsyncd listening on //p' "$work/out")
metrics=$(sed -n 's/^lipsyncd metrics on //p' "$work/out")
[[ -n $address && -n $metrics ]] || { echo "soak: lipsyncd did not start"; cat "$work/err"; exit 1; }

rss_kb() { awk '/^VmRSS/ {print $2}' "/proc/$server/status"; }
fds() { ls "/proc/$server/fd" | wc -l; }

PYTHONPATH="$build/clients/python/generated" /usr/bin/python3 "$here/soak/soak_load.py" "$address" "$duration" \
  >"$work/load" 2>&1 &
load=$!

warmup=$(( duration / 4 > 20 ? duration / 4 : 20 ))
start=$(date +%s)
rss_samples=(); fd_samples=()
while kill -0 "$load" 2>/dev/null; do
  sleep 10
  kill -0 "$server" 2>/dev/null || { echo "soak: lipsyncd died"; cat "$work/err"; exit 1; }
  elapsed=$(( $(date +%s) - start ))
  rss=$(rss_kb); fd=$(fds)
  echo "soak: t=${elapsed}s rss=$((rss / 1024))MB fds=$fd"
  if (( elapsed >= warmup )); then rss_samples+=("$rss"); fd_samples+=("$fd"); fi
done
load_status=0
wait "$load" || load_status=$?
cat "$work/load"
scrape=$(exec 3<>"/dev/tcp/${metrics%:*}/${metrics##*:}" && printf 'GET /metrics HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n' >&3 && cat <&3)
echo "$scrape" | grep -E '^lipsyncd_(calls_total|refusals_total)' | sed 's/^/soak: /' | head -40

kill -TERM "$server"
exit_status=0
wait "$server" || exit_status=$?
server=""

# The largest of samples[from, to).
largest() { local -n values=$1; local max=0; for ((i = $2; i < $3; i++)); do (( values[i] > max )) && max=${values[i]}; done; echo "$max"; }

failed=0
count=${#rss_samples[@]}
if (( count < 2 )); then
  echo "soak: ${count} samples after the warm-up (${warmup}s): run longer"; failed=1
else
  half=$(( count / 2 ))
  rss_first=$(largest rss_samples 0 "$half"); rss_second=$(largest rss_samples "$half" "$count")
  fds_first=$(largest fd_samples 0 "$half"); fds_second=$(largest fd_samples "$half" "$count")
  growth_mb=$(( (rss_second - rss_first) / 1024 ))
  echo "soak: after warm-up (${warmup}s, ${count} samples): largest rss $((rss_first / 1024)) MB, then $((rss_second / 1024)) MB (${growth_mb} MB, slack ${rss_slack_mb}); largest fds ${fds_first}, then ${fds_second} (slack ${fd_slack})"
  (( growth_mb > rss_slack_mb )) && { echo "soak: resident memory grew"; failed=1; }
  (( fds_second - fds_first > fd_slack )) && { echo "soak: open file descriptors grew"; failed=1; }
fi
(( load_status != 0 )) && { echo "soak: calls got statuses they should not have"; failed=1; }
(( exit_status != 0 )) && { echo "soak: lipsyncd exited $exit_status after SIGTERM"; failed=1; }
exit $failed
