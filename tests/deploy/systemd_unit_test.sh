#!/usr/bin/env bash
# systemd_unit_test.sh SOURCE_DIR LIPSYNCD: `systemd-analyze verify` of deploy/systemd/lipsyncd.service
# (with ExecStart pointing at the built lipsyncd) must print nothing; and the unit must keep the
# properties docs/deploy.md promises. Skips (77) only where systemd-analyze is not installed.
set -euo pipefail
unit=$1/deploy/systemd/lipsyncd.service
command -v systemd-analyze >/dev/null || { echo "SKIP: systemd-analyze is not installed (apt-get install systemd)"; exit 77; }
work=$(mktemp -d "${TMPDIR:-/tmp}/lipsync-unit.XXXXXX")
trap 'rm -rf "$work"' EXIT
sed "s|/usr/bin/lipsyncd|$(realpath "$2")|" "$unit" >"$work/lipsyncd.service"
out=$(systemd-analyze verify "$work/lipsyncd.service" 2>&1) || true
[[ -z "$out" ]] || { echo "FAIL: systemd-analyze verify: $out"; exit 1; }
for line in "DynamicUser=yes" "ExecReload=/bin/kill -HUP \$MAINPID" "KillSignal=SIGTERM" "NoNewPrivileges=yes" \
            "ProtectSystem=strict" "CapabilityBoundingSet=" "ExecStart=/usr/bin/lipsyncd --config /etc/lipsyncd/lipsyncd.json"; do
  grep -qxF -- "$line" "$unit" || { echo "FAIL: $unit lacks '$line'"; exit 1; }
done
# The stop timeout outlasts the configured drain.
drain_ms=$(sed -n 's/.*"drain-deadline-ms": *\([0-9]*\).*/\1/p' "$1/deploy/systemd/lipsyncd.json")
stop_s=$(sed -n 's/^TimeoutStopSec=//p' "$unit")
(( stop_s * 1000 > drain_ms )) || { echo "FAIL: TimeoutStopSec=$stop_s does not outlast drain-deadline-ms=$drain_ms"; exit 1; }
echo "PASS: the unit verifies, runs unprivileged, reloads with SIGHUP and outlasts the drain"
