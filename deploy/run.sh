#!/usr/bin/env bash
# Installs what is missing, builds, and runs lipsyncd with the built-in model on
# 127.0.0.1:50051 (in the foreground; Ctrl-C drains running streams and stops it).
# Extra arguments go to lipsyncd, e.g. --listen 127.0.0.1:6000 or --log-level debug.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

bash deploy/install-deps.sh
bash deploy/build.sh
exec build/server/lipsyncd --listen 127.0.0.1:50051 "$@"
