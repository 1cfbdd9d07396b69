#!/usr/bin/env bash
# Builds the Debian packages lipsyncd, lipsync-client-dev and python3-lipsync-client into
# build-package/ (configured for /usr, so the unit's config lands in /etc/lipsyncd/).
# Install them on Debian 12 with: apt-get install ./build-package/*.deb
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
cmake -S . -B build-package -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX=/usr \
  -DLIPSYNC_BUILD_TESTS=OFF -DLIPSYNC_BUILD_BENCHMARKS=OFF "$@"
cmake --build build-package
(cd build-package && cpack -G DEB)
ls -l build-package/*.deb
