#!/usr/bin/env bash
# Soak: runs lipsyncd for DURATION seconds under mixed load (tools/soak/soak_load.py:
# streams, followers, subscribers that stall, cancellations, bad and oversize requests,
# face streams, Render) and checks that resident memory and open file descriptors stay
# flat after warm-up (the first quarter of the run, at least 20 s). They are sampled at
# quiet moments only (every DURATION/60 s, at least 5: the load pauses until no call runs
# and no session is held); the lowest sample of the last third may exceed the lowest of
# the first third by at most SOAK_RSS_SLACK_MB (default 16 MB) and SOAK_FD_SLACK fds
# (default 8): tools/soak/soak_judge.py says why. Then SIGTERM: exit 0 expected.
#
#   tools/soak.sh DURATION [BUILD_DIR]      e.g. tools/soak.sh 1800 build
#
# Prints each quiet sample and a summary; exit status 1 on growth, a call with a status
# it should not get, or a bad exit. Needs Debian's /usr/bin/python3 with python3-grpcio
# and the stubs the build generates (clients/python/generated).
set -euo pipefail

duration=${1:?usage: tools/soak.sh DURATION_SECONDS [BUILD_DIR]}
build=${2:-build}
here=$(cd "$(dirname "$0")" && pwd)
source "$here/../tests/support/listening_address.sh"
rss_slack_mb=${SOAK_RSS_SLACK_MB:-16}
fd_slack=${SOAK_FD_SLACK:-8}
warmup=$(( duration / 4 > 20 ? duration / 4 : 20 ))
work=$(mktemp -d)
trap 'kill "$server" 2>/dev/null || true; kill "$load" 2>/dev/null || true; rm -rf "$work"' EXIT

# lipsyncd as shipped: it fixes glibc's mmap threshold itself (server/src/main.cpp), so what the
# soak measures is what a deployment gets.
"$build/server/lipsyncd" --listen 127.0.0.1:0 --metrics-listen 127.0.0.1:0 --log-level warn \
  --subscriber-queue-frames 200 --stalled-subscriber-ms 500 --session-retention-ms 1000 \
  --face-threads 1 >"$work/out" 2>"$work/err" &
server=$!
for _ in $(seq 100); do grep -q "metrics on" "$work/out" && break; sleep 0.1; done
metrics=$(sed -n 's/^lipsyncd metrics on //p' "$work/out")
if ! address=$(listening_address "$work/out") || [[ -z $metrics ]]; then
  echo "soak: lipsyncd did not start"; cat "$work/err"; exit 1
fi

quiet_every=$(( duration / 60 > 5 ? duration / 60 : 5 ))
PYTHONPATH="$build/clients/python/generated" /usr/bin/python3 "$here/soak/soak_load.py" "$address" "$metrics" \
  "$server" "$duration" --quiet-every "$quiet_every" --warmup "$warmup" --rss-slack-mb "$rss_slack_mb" \
  --fd-slack "$fd_slack" &
load=$!
load_status=0
wait "$load" || load_status=$?
load=""
kill -0 "$server" 2>/dev/null || { echo "soak: lipsyncd died"; cat "$work/err"; exit 1; }
scrape=$(exec 3<>"/dev/tcp/${metrics%:*}/${metrics##*:}" && printf 'GET /metrics HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n' >&3 && cat <&3)
echo "$scrape" | grep -E '^lipsyncd_(calls_total|refusals_total)' | sed 's/^/soak: /' | head -40

kill -TERM "$server"
exit_status=0
wait "$server" || exit_status=$?
server=""

failed=0
(( load_status != 0 )) && failed=1
(( exit_status != 0 )) && { echo "soak: lipsyncd exited $exit_status after SIGTERM"; failed=1; }
exit $failed
