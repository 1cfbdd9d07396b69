#!/usr/bin/env bash
# Installs what is missing, builds, and runs every test; exits with ctest's status.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

bash deploy/install-deps.sh
bash deploy/build.sh
# The 2-minute soak (label soak) runs on demand: `ctest --test-dir build -L soak` (docs/server.md).
ctest --test-dir build --output-on-failure -j2 -LE soak
