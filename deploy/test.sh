#!/usr/bin/env bash
# Installs what is missing, builds, and runs every test; exits with ctest's status.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

bash deploy/install-deps.sh
bash deploy/build.sh
# Every test, the 2-minute soak (label soak: docs/server.md, "Soak") among them.
ctest --test-dir build --output-on-failure -j2
