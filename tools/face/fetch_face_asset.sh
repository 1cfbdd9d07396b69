#!/bin/sh
# Regenerates (or, with --check, verifies) data/face/ from the pinned npm package
# @mediapipe/face_mesh: fetches it with `npm pack`, checks the tarball's sha256, extracts
# the canonical face mesh (tools/face/extract_canonical_mesh.py) and writes
# data/face/canonical_face.json, LICENSE-Apache-2.0.txt and NOTICE.
# Builds and tests never run this: the derived files are committed.
set -eu

PACKAGE='@mediapipe/face_mesh@0.4.1657299874'
SHA256='c08a7e0742a326285da666cf81d77c8b6f3a181a2ee948cadaf166008e0d3bc7'
LICENSE_TEXT=/usr/share/common-licenses/Apache-2.0

root=$(cd "$(dirname "$0")/../.." && pwd)
out="$root/data/face"
check=0
[ "${1:-}" = "--check" ] && check=1

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT INT TERM
(cd "$work" && npm pack --silent "$PACKAGE" >/dev/null)
tarball=$(ls "$work"/*.tgz)
actual=$(sha256sum "$tarball" | cut -d' ' -f1)
if [ "$actual" != "$SHA256" ]; then
  echo "sha256 mismatch for $PACKAGE: expected $SHA256, got $actual" >&2
  exit 1
fi
tar -xzf "$tarball" -C "$work"

mkdir -p "$work/out"
/usr/bin/python3 "$root/tools/face/extract_canonical_mesh.py" "$work/package" "$work/out/canonical_face.json"
cp "$LICENSE_TEXT" "$work/out/LICENSE-Apache-2.0.txt"
cat > "$work/out/NOTICE" <<NOTICE
MediaPipe canonical face mesh, Copyright 2020 The MediaPipe Authors, Apache-2.0
(LICENSE-Apache-2.0.txt). Source: npm package $PACKAGE (sha256 $SHA256),
file geometry_pipeline_metadata_landmarks.binarypb inside face_mesh_solution_packed_assets.data.
Derived: canonical_face.json is that file's canonical mesh (positions in centimetres, UVs,
triangles) and Procrustes landmark weights, decoded and rewritten as JSON by
tools/face/extract_canonical_mesh.py; the geometry is unchanged. rig.json is lipsyncd's own work.
NOTICE

if [ $check -eq 1 ]; then
  status=0
  for f in canonical_face.json LICENSE-Apache-2.0.txt NOTICE; do
    cmp -s "$work/out/$f" "$out/$f" || { echo "data/face/$f differs from what the script writes" >&2; status=1; }
  done
  [ $status -eq 0 ] && echo "data/face matches $PACKAGE"
  exit $status
fi
mkdir -p "$out"
cp "$work/out/canonical_face.json" "$work/out/LICENSE-Apache-2.0.txt" "$work/out/NOTICE" "$out/"
echo "wrote $out/canonical_face.json, LICENSE-Apache-2.0.txt, NOTICE"
