#!/usr/bin/env bash
# Installs what is missing, builds, and renders the demo utterance with the
# command-line client (the track goes to ./lipsync-demo.json).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

bash deploy/install-deps.sh
bash deploy/build.sh
build/clients/cli/lipsync demo
