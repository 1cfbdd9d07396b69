#!/usr/bin/python3
"""Extract the MediaPipe canonical face mesh from the @mediapipe/face_mesh npm package.

The package ships its models as one packed file system,
face_mesh_solution_packed_assets.data, whose file table (name, start, end byte) is a
JSON-like list inside face_mesh_solution_packed_assets_loader.js. The entry
geometry_pipeline_metadata_landmarks.binarypb is a protobuf (mediapipe
GeometryPipelineMetadata):
  field 1 (message) canonical_mesh: 1 vertex_type, 2 primitive_type,
      3 repeated float vertex_buffer (x, y, z, u, v per vertex, not packed),
      4 repeated uint32 index_buffer (varints, three per triangle)
  field 2 (message, repeated) procrustes_landmark_basis: 1 landmark_id, 2 weight
This script decodes it with the standard library only and writes
data/face/canonical_face.json (format in docs/face.md).

Usage: extract_canonical_mesh.py PACKAGE_DIR OUTPUT_JSON
"""
import json
import re
import struct
import sys

ENTRY = "geometry_pipeline_metadata_landmarks.binarypb"


def read_varint(data, pos):
    value = 0
    shift = 0
    while True:
        byte = data[pos]
        pos += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if not byte & 0x80:
            return value, pos


def fields(data):
    """Yields (field number, wire type, value) of one protobuf message."""
    pos = 0
    while pos < len(data):
        key, pos = read_varint(data, pos)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, pos = read_varint(data, pos)
        elif wire == 1:
            value, pos = data[pos:pos + 8], pos + 8
        elif wire == 2:
            length, pos = read_varint(data, pos)
            value, pos = data[pos:pos + length], pos + length
        elif wire == 5:
            value, pos = data[pos:pos + 4], pos + 4
        else:
            raise ValueError(f"unsupported wire type {wire} for field {number}")
        yield number, wire, value


def packed_varints(data):
    pos = 0
    while pos < len(data):
        value, pos = read_varint(data, pos)
        yield value


def decode(blob):
    floats, indices, landmarks = [], [], []
    for number, wire, value in fields(blob):
        if number == 1:
            for sub, sub_wire, sub_value in fields(value):
                if sub == 3 and sub_wire == 5:
                    floats.append(struct.unpack("<f", sub_value)[0])
                elif sub == 3 and sub_wire == 2:
                    floats.extend(struct.unpack(f"<{len(sub_value) // 4}f", sub_value))
                elif sub == 4 and sub_wire == 0:
                    indices.append(sub_value)
                elif sub == 4 and sub_wire == 2:
                    indices.extend(packed_varints(sub_value))
        elif number == 2:
            landmark_id, weight = 0, 0.0
            for sub, sub_wire, sub_value in fields(value):
                if sub == 1:
                    landmark_id = sub_value
                elif sub == 2:
                    weight = struct.unpack("<f", sub_value)[0]
            landmarks.append((landmark_id, weight))
    if len(floats) % 5 or len(indices) % 3:
        raise ValueError("vertex or index buffer has a partial element")
    return floats, indices, landmarks


def number(value):
    """Shortest text that reads back as the same float32."""
    for digits in range(6, 10):
        text = f"{value:.{digits}g}"
        if struct.unpack("<f", struct.pack("<f", float(text)))[0] == value:
            return text
    return f"{value:.9g}"


def main():
    package_dir, output = sys.argv[1], sys.argv[2]
    loader = open(f"{package_dir}/face_mesh_solution_packed_assets_loader.js").read()
    match = re.search(r'"filename":\s*"[^"]*' + re.escape(ENTRY) + r'",\s*"start":\s*(\d+),\s*"end":\s*(\d+)', loader)
    if not match:
        sys.exit(f"{ENTRY} not found in the loader's file table")
    start, end = int(match.group(1)), int(match.group(2))
    with open(f"{package_dir}/face_mesh_solution_packed_assets.data", "rb") as packed:
        packed.seek(start)
        blob = packed.read(end - start)
    floats, indices, landmarks = decode(blob)
    vertex_count = len(floats) // 5
    rows = [floats[i * 5:i * 5 + 5] for i in range(vertex_count)]
    lines = [
        "{",
        '  "format": "lipsync-face-asset",',
        '  "version": 1,',
        '  "source": "MediaPipe canonical face mesh, npm @mediapipe/face_mesh@0.4.1657299874, '
        f'{ENTRY} bytes {start}..{end} of face_mesh_solution_packed_assets.data",',
        '  "license": "Apache-2.0, Copyright 2020 The MediaPipe Authors (see LICENSE-Apache-2.0.txt and NOTICE)",',
        '  "units": "centimetres; x to the subject\'s left, y up, z toward the viewer; uv in [0, 1]",',
        '  "positions_cm": [',
        ",\n".join(f"    [{number(r[0])}, {number(r[1])}, {number(r[2])}]" for r in rows),
        "  ],",
        '  "uvs": [',
        ",\n".join(f"    [{number(r[3])}, {number(r[4])}]" for r in rows),
        "  ],",
        '  "triangles": [',
        ",\n".join(f"    [{indices[i]}, {indices[i + 1]}, {indices[i + 2]}]" for i in range(0, len(indices), 3)),
        "  ],",
        '  "procrustes_landmarks": [',
        ",\n".join(f'    {{"id": {i}, "weight": {number(w)}}}' for i, w in landmarks),
        "  ]",
        "}",
    ]
    with open(output, "w") as out:
        out.write("\n".join(lines) + "\n")
    json.load(open(output))
    print(f"{output}: {vertex_count} vertices, {len(indices) // 3} triangles, {len(landmarks)} procrustes landmarks")


if __name__ == "__main__":
    main()
