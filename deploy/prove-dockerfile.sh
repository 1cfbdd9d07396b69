#!/usr/bin/env bash
# Proves the Dockerfile without a container engine: performs its build steps in a fresh Debian 12
# root made with debootstrap (a chroot), copies what its runtime stage copies into a second fresh
# root with only the runtime packages, then runs the built lipsyncd there as the non-root user,
# asks its gRPC health service (the HEALTHCHECK) and makes one request. Prints the time taken and
# the size of the runtime root. The package lists are read from the Dockerfile itself, so the two
# cannot drift. Needs root, debootstrap and about 2 GB in WORK_DIR; takes long (a full build).
#   bash deploy/prove-dockerfile.sh [WORK_DIR]      (default /var/tmp/lipsync-prove)
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
source_dir=$PWD
source tests/support/listening_address.sh
work=${1:-/var/tmp/lipsync-prove}
mirror=${DEBIAN_MIRROR:-http://deb.debian.org/debian}
started=$(date +%s)
command -v debootstrap >/dev/null || { echo "prove-dockerfile: apt-get install debootstrap" >&2; exit 1; }
[[ $(id -u) -eq 0 ]] || { echo "prove-dockerfile: run as root (debootstrap, chroot)" >&2; exit 1; }

# The packages of each stage's `apt-get install` in the Dockerfile.
stage_packages() {  # STAGE_NAME
  awk -v stage="$1" '
    /^FROM / { in_stage = ($NF == stage) }
    in_stage && /apt-get install/ { collecting = 1 }
    in_stage && collecting { print; if ($0 !~ /\\$/ || $0 ~ /&&.*rm -rf/) collecting = 0 }
  ' Dockerfile | tr ' \\' '\n\n' | grep -E '^[a-z0-9][a-z0-9.+-]+$' |
    grep -vE '^(apt-get|install|rm|useradd|DEBIAN_FRONTEND=noninteractive)$' | sort -u
}
build_packages=$(stage_packages build)
runtime_packages=$(stage_packages runtime)

mounted=()
cleanup() {
  for ((i = ${#mounted[@]} - 1; i >= 0; i--)); do umount -l "${mounted[i]}" 2>/dev/null || true; done
  if [[ -n "${server_pid:-}" ]]; then kill "$server_pid" 2>/dev/null || true; fi
}
trap cleanup EXIT
make_root() {  # DIR: a fresh minimal Debian 12 with its own /proc and a private /dev
  if findmnt -rn -o TARGET | grep -q "^$1/"; then  # rm -rf must never walk into a mount
    echo "prove-dockerfile: something is still mounted under $1: unmount it first" >&2; exit 1
  fi
  rm -rf "$1"
  debootstrap --variant=minbase bookworm "$1" "$mirror" >"$1.debootstrap.log" 2>&1 ||
    { tail -20 "$1.debootstrap.log"; exit 1; }
  cp /etc/resolv.conf "$1/etc/resolv.conf"
  mount -t proc proc "$1/proc"; mounted+=("$1/proc")
  # Never bind the host's /dev: package scripts in the chroot may replace /dev/null (it happened:
  # the host's /dev/null became a plain file). A private tmpfs with the few nodes apt needs.
  mount -t tmpfs -o mode=755,nosuid tmpfs "$1/dev"; mounted+=("$1/dev")
  mknod -m 666 "$1/dev/null" c 1 3
  mknod -m 666 "$1/dev/zero" c 1 5
  mknod -m 666 "$1/dev/random" c 1 8
  mknod -m 666 "$1/dev/urandom" c 1 9
  mkdir -p "$1/dev/pts" "$1/dev/shm"
  mount -t devpts -o newinstance,ptmxmode=0666 devpts "$1/dev/pts" 2>/dev/null && mounted+=("$1/dev/pts") || true
}
in_root() { chroot "$1" /usr/bin/env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root DEBIAN_FRONTEND=noninteractive "${@:2}"; }

mkdir -p "$work"
echo "== build stage: debootstrap, then apt-get install $(echo $build_packages | wc -w) packages"
make_root "$work/build"
in_root "$work/build" apt-get update -qq
in_root "$work/build" apt-get install -y -qq --no-install-recommends $build_packages >/dev/null
mkdir -p "$work/build/src"
for path in CMakeLists.txt cmake core proto server clients data docs deploy README.md; do
  cp -r "$source_dir/$path" "$work/build/src/"
done
rm -rf "$work/build/src/build"
build_started=$(date +%s)
# The Dockerfile's build RUN, word for word.
in_root "$work/build" /bin/sh -c 'cd /src && cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_INSTALL_PREFIX=/usr -DLIPSYNC_BUILD_TESTS=OFF -DLIPSYNC_BUILD_BENCHMARKS=OFF -DLIPSYNC_BUILD_PYTHON=OFF \
  && cmake --build build --target lipsyncd lipsync && DESTDIR=/staging cmake --install build --component server' \
  >"$work/build.log" 2>&1 || { tail -30 "$work/build.log"; exit 1; }
build_s=$(( $(date +%s) - build_started ))

echo "== runtime stage: debootstrap, apt-get install $runtime_packages"
make_root "$work/runtime"
in_root "$work/runtime" apt-get update -qq
in_root "$work/runtime" apt-get install -y -qq --no-install-recommends $runtime_packages >/dev/null
in_root "$work/runtime" /bin/sh -c 'rm -rf /var/lib/apt/lists/* && useradd --system --uid 10001 --no-create-home --shell /usr/sbin/nologin lipsyncd'
cp "$work/build/staging/usr/bin/lipsyncd" "$work/build/staging/usr/bin/lipsync" "$work/runtime/usr/bin/"
cp -r "$work/build/staging/usr/share/lipsync" "$work/runtime/usr/share/"

echo "== run: lipsyncd as uid 10001, the health check, one request"
chroot --userspec=10001:10001 "$work/runtime" /usr/bin/env -i LIPSYNCD_LISTEN=127.0.0.1:0 \
  LIPSYNCD_REPLICA_NAME=proof /usr/bin/lipsyncd >"$work/server.out" 2>"$work/server.err" &
server_pid=$!
address=$(wait_for_listening_address "$work/server.out" 10) ||
  { echo "lipsyncd did not start:"; cat "$work/server.err"; exit 1; }
[[ $(ps -o uid= -p "$server_pid" | tr -d ' ') == 10001 ]] || { echo "lipsyncd does not run as uid 10001"; exit 1; }
health=$(chroot --userspec=10001:10001 "$work/runtime" /usr/bin/lipsync health --server "$address")
cp "$source_dir/tests/data/cli/bump_map.json" "$work/runtime/tmp/utterance.json"
frames=$(chroot --userspec=10001:10001 "$work/runtime" /usr/bin/lipsync stream /tmp/utterance.json \
  --server "$address" --session proof --format csv -o - | wc -l)
kill -TERM "$server_pid"; wait "$server_pid"; server_pid=
runtime_size=$(du -sx --exclude=proc --exclude=sys --exclude=dev -m "$work/runtime" | cut -f1)
echo "prove-dockerfile: health=$health, one Animate stream gave $((frames - 1)) frames (CSV rows)"
echo "prove-dockerfile: total $(( $(date +%s) - started )) s (build step ${build_s} s); runtime root ${runtime_size} MB"
