#!/usr/bin/env bash
# Configures and builds lipsyncd in ./build with Ninja (optimised: -O3, which the coarticulation loops need to vectorise).
# Extra arguments go to the configure step, e.g. -DLIPSYNC_WARNINGS_AS_ERRORS=ON.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release "$@"
cmake --build build
