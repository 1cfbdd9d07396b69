// A hand-written protobuf reader for the messages the viewer's WebSocket carries: each binary
// message is one serialised lipsync.v1.TrackMessage (proto/lipsync/v1/lipsync.proto), exactly what
// a gRPC Subscribe call receives. Only the fields the viewer uses are decoded; unknown fields are
// skipped by wire type, so a newer server's additions do not break an older page. Repeated scalars
// are read packed or unpacked, as proto3 parsers must. int64 values become JavaScript numbers
// (exact up to 2^53 µs, about 285 years).
"use strict";

class ProtoReader {
  constructor(bytes) {
    this.bytes = bytes;
    this.view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    this.pos = 0;
  }
  done() { return this.pos >= this.bytes.length; }
  varint() {
    let value = 0, scale = 1, byte;
    do {
      if (this.pos >= this.bytes.length) throw new Error("truncated varint");
      byte = this.bytes[this.pos++];
      value += (byte & 0x7f) * scale;
      scale *= 128;
    } while (byte & 0x80);
    return value >= 2 ** 63 ? value - 2 ** 64 : value;  // a negative int64
  }
  float() { const v = this.view.getFloat32(this.pos, true); this.pos += 4; return v; }
  bytesField() {
    const length = this.varint();
    if (this.pos + length > this.bytes.length) throw new Error("truncated field");
    const out = this.bytes.subarray(this.pos, this.pos + length);
    this.pos += length;
    return out;
  }
  string() { return new TextDecoder().decode(this.bytesField()); }
  skip(wireType) {
    if (wireType === 0) this.varint();
    else if (wireType === 1) this.pos += 8;
    else if (wireType === 2) this.bytesField();
    else if (wireType === 5) this.pos += 4;
    else throw new Error("unsupported wire type " + wireType);
  }
  /// Reads fields until the end, calling handlers[field](reader, wireType); others are skipped.
  fields(handlers) {
    while (!this.done()) {
      const key = this.varint();
      const field = Math.floor(key / 8), wireType = key & 7;
      const handler = handlers[field];
      if (handler) handler(this, wireType); else this.skip(wireType);
    }
  }
}

function message(reader, decode) { return decode(new ProtoReader(reader.bytesField())); }

/// Appends a repeated varint field (packed or not) to `out`.
function repeatedVarint(reader, wireType, out) {
  if (wireType !== 2) { out.push(reader.varint()); return; }
  const inner = new ProtoReader(reader.bytesField());
  while (!inner.done()) out.push(inner.varint());
}

/// Appends a repeated float field (packed or not) to `out` (an array of numbers).
function repeatedFloat(reader, wireType, out) {
  if (wireType !== 2) { out.push(reader.float()); return; }
  const inner = new ProtoReader(reader.bytesField());
  while (!inner.done()) out.push(inner.float());
}

function decodeMediaClock(r) {
  const anchor = { clock: "", utteranceZeroUs: 0 };
  r.fields({ 1: (r) => { anchor.clock = r.string(); }, 2: (r) => { anchor.utteranceZeroUs = r.varint(); } });
  return anchor;
}

function decodeMeshTopology(r) {
  const mesh = { vertexCount: 0, softVertexCount: 0, restPositions: [], triangles: [], parts: [],
                 encoding: 1, quantisationScaleM: 0, quantisationOffsetM: [] };
  r.fields({
    2: (r) => { mesh.vertexCount = r.varint(); },
    3: (r) => { mesh.softVertexCount = r.varint(); },
    5: (r, w) => repeatedFloat(r, w, mesh.restPositions),
    6: (r, w) => repeatedVarint(r, w, mesh.triangles),
    8: (r, w) => repeatedVarint(r, w, mesh.parts),
    9: (r) => { mesh.encoding = r.varint(); },
    10: (r) => { mesh.quantisationScaleM = r.float(); },
    11: (r, w) => repeatedFloat(r, w, mesh.quantisationOffsetM),
  });
  return mesh;
}

function decodeHeader(r) {
  const header = { model: "", fps: 0, channels: [], arkitNames: [], session: "", mediaClock: null,
                   mesh: null, visemeVocabulary: 0, visemeNames: [] };
  r.fields({
    1: (r) => { header.model = r.string(); },
    2: (r) => { header.fps = r.varint(); },
    3: (r) => { header.channels.push(r.string()); },
    4: (r) => { header.arkitNames.push(r.string()); },
    5: (r) => { header.session = r.string(); },
    6: (r) => { header.mediaClock = message(r, decodeMediaClock); },
    8: (r) => { header.mesh = message(r, decodeMeshTopology); },
    9: (r) => { header.visemeVocabulary = r.varint(); },
    10: (r) => { header.visemeNames.push(r.string()); },
  });
  return header;
}

function decodeFrameBatch(r) {
  const batch = { firstFrame: 0, tUs: [], kinds: [], values: [], arkit: [], meshPositions: [],
                  meshPositionsInt16: null, visemeWeights: [], visemeEvents: [] };
  r.fields({
    1: (r) => { batch.firstFrame = r.varint(); },
    2: (r, w) => repeatedVarint(r, w, batch.tUs),
    3: (r, w) => repeatedVarint(r, w, batch.kinds),
    4: (r, w) => repeatedFloat(r, w, batch.values),
    5: (r, w) => repeatedFloat(r, w, batch.arkit),
    6: (r, w) => repeatedFloat(r, w, batch.meshPositions),
    7: (r) => { batch.meshPositionsInt16 = r.bytesField(); },
    8: (r, w) => repeatedFloat(r, w, batch.visemeWeights),
    9: (r) => {
      batch.visemeEvents.push(message(r, (m) => {
        const event = { viseme: 0, startUs: 0 };
        m.fields({ 1: (m) => { event.viseme = m.varint(); }, 2: (m) => { event.startUs = m.varint(); } });
        return event;
      }));
    },
  });
  return batch;
}

function decodeSummary(r) {
  const summary = { frames: 0, phonemes: 0, durationUs: 0 };
  r.fields({
    1: (r) => { summary.frames = r.varint(); },
    2: (r) => { summary.phonemes = r.varint(); },
    3: (r) => { summary.durationUs = r.varint(); },
  });
  return summary;
}

/// One TrackMessage: {header}, {frames} or {summary}.
function decodeTrackMessage(bytes) {
  const out = {};
  new ProtoReader(bytes).fields({
    1: (r) => { out.header = message(r, decodeHeader); },
    2: (r) => { out.frames = message(r, decodeFrameBatch); },
    3: (r) => { out.summary = message(r, decodeSummary); },
  });
  return out;
}
