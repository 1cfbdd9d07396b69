#!/usr/bin/env bash
# pip_install_test.sh SOURCE_DIR: `pip install` of clients/python into a fresh venv (Debian's
# setuptools, --no-build-isolation, no index: PyPI is not reachable), then `import lipsync_client`
# and the generated stubs from outside the source tree, without PYTHONPATH. The sources are copied
# first so that the build leaves nothing in the checkout.
set -euo pipefail
source_dir=$(cd "$1" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/lipsync-pip.XXXXXX")
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/src/clients"
cp -r "$source_dir/proto" "$work/src/proto"
cp -r "$source_dir/clients/python" "$work/src/clients/python"
/usr/bin/python3 -m venv --system-site-packages --without-pip "$work/venv"
unset PYTHONPATH
"$work/venv/bin/python" -m pip install --quiet --no-build-isolation --no-index "$work/src/clients/python" \
  >"$work/pip.log" 2>&1 || { cat "$work/pip.log"; exit 1; }
cd "$work"
out=$("$work/venv/bin/python" -c "
import lipsync_client, lipsync_client.client
from lipsync.v1 import lipsync_pb2, lipsync_pb2_grpc
print(lipsync_client.__file__.startswith('$work/venv/'), lipsync_pb2.__file__.startswith('$work/venv/'),
      hasattr(lipsync_pb2_grpc, 'LipSyncStub'), lipsync_client.client.session_metadata('s'))
")
expected="True True True (('x-lipsync-session', 's'),)"
[[ "$out" == "$expected" ]] || { echo "FAIL: got '$out', expected '$expected'"; exit 1; }
echo "PASS: pip installed lipsync-client into a venv; lipsync_client and lipsync.v1 import without PYTHONPATH"
