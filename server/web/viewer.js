// lipsyncd's browser viewer (docs/viewer.md). It follows one session over the WebSocket /ws (each
// binary message a serialised TrackMessage, decoded by track_decoder.js) and draws, every
// animation frame, the track's frame for the current utterance time:
//
// - Time. The header's media-clock anchor says when utterance time 0 plays. On the "unix" clock
//   (the producer's wall clock; lipsyncd's quick try uses it) the page shows frame t at wall time
//   utterance_zero_us + t, so every viewer of a session shows the same frame at the same moment.
//   With another clock, or none, the page starts utterance time 0 when the header arrives.
// - Audio. An audio file or URL (?audio=URL, or chosen on the page) plays slaved to that clock: it
//   starts at utterance time 0 (or at the current time when the page joins late), and every
//   kSteerIntervalMs its position is compared with the anchor's (the drift, shown in #drift) and
//   steered: the playback rate is trimmed in proportion to the drift; a start or seek whose
//   pipeline restart left the audio more than kSeekUnlockedUs behind is seeked again ahead by the
//   lag measured; kLockSamples measurements in a row within kLockUs lock it, and a locked audio
//   is seeked only beyond kResyncUs. The face follows the anchor, not the audio, so that a stalled
//   audio element never freezes the face.
// - The face. With the mesh output (the header carries a MeshTopology) the page draws the server's
//   simulated vertices. Otherwise it poses the viewer's face (/face.json, data/face/
//   viewer_face.json: the physics face fitted as ARKit blendshapes by tools/face/make_viewer_face)
//   with the frame's ARKit weights: rest + Σ w_k Δ_k. Skin and lips are lit; the mouth cavity, teeth
//   and tongue are drawn in flat colours (kOpenMouthColours) so an open mouth can be measured on a
//   screenshot.
//
// Its state is on window.lipsyncViewer and in the elements #frame-time (µs), #viseme and #drift.
"use strict";

const kResyncUs = 100000;       // locked audio further than this from the anchor is seeked
const kSeekUnlockedUs = 60000;  // a started or seeked audio further than this is seeked again
const kLockUs = 30000;          // ... and locked after kLockSamples measurements in a row within this
const kLockSamples = 5;
const kMaxLeadUs = 500000;
const kSteerIntervalMs = 20;
const kRetryNotFoundMs = 250;   // a session not (yet) there is asked for again this often
const kRateGainPerSecond = 4;   // playback-rate trim per second of drift
const kMaxRateTrim = 0.15;
const kSettleAfterStartMs = 60; // after a start or seek, drift is measured once the audio runs again, and this long after

// Mesh parts (lipsync.v1.MeshPart) and their colours, linear-ish RGB 0..1.
const kPartColours = [
  [0.87, 0.70, 0.60],  // skin (lit)
  [0.72, 0.36, 0.38],  // inner lip (lit)
  [0.20, 0.02, 0.12],  // mouth cavity (flat)
  [0.96, 0.95, 0.88],  // upper teeth (flat)
  [0.96, 0.95, 0.88],  // lower teeth (flat)
  [0.85, 0.30, 0.40],  // tongue (flat)
];
const kLipColour = [0.76, 0.42, 0.44];
const kNotFoundCloseCode = 4005;  // 4000 + gRPC NOT_FOUND
const kLitParts = new Set([0, 1]);
/// What an open mouth shows on a screenshot (8-bit sRGB as drawn): cavity, teeth, tongue.
const kOpenMouthColours = [2, 3, 5].map((p) => kPartColours[p].map((c) => Math.round(c * 255)));
// Outer lip contour (MediaPipe landmark ids): skin inside it is drawn in the lip colour.
const kOuterLip = [61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291, 375, 321, 405, 314, 17, 84, 181, 91, 146];
const kUpperInnerLip = 13, kLowerInnerLip = 14;

const params = new URLSearchParams(location.search);
// A server with --api-keys: the key travels to lipsyncd as ?key= (docs/viewer.md).
const apiKey = params.get("key");
const canvas = document.getElementById("face");
const audio = document.getElementById("audio");
const elements = Object.fromEntries(
  ["status", "session", "frame-time", "viseme", "drift", "mode", "bars", "try-result"].map(
    (id) => [id, document.getElementById(id)]));

const viewer = {
  connected: false,
  waiting: false,        // the session does not exist yet: the page asks again every kRetryNotFoundMs
  session: params.get("session") || null,
  mode: null,            // "mesh", "blendshapes" or "rest" (no face data in the stream)
  clock: null,           // "unix" (the anchor's) or "arrival"
  utteranceZeroUs: null, // the anchor
  utteranceTime: null,   // µs now on the anchor's timeline
  frameTime: null,       // µs of the frame on screen
  frameIndex: null,
  viseme: null,
  drift: null,           // µs: audio position − anchor position (null: no audio playing)
  locked: false,         // the audio reached the anchor (|drift| < kLockUs) since its last seek
  lockedAtUs: null,      // utterance time when it did
  maxAbsDrift: null,     // µs, over the measurements while locked
  lockedDrifts: [],      // µs, |drift| of the last 1,000 measurements while locked
  driftSamples: 0,
  lockedSamples: 0,      // measurements while locked
  resyncs: 0,            // seeks after the start (the start's own lag, or a drift beyond kResyncUs)
  mouthOpen: null,       // mm between the inner lips (landmarks 13 and 14) on screen
  mouthRect: null,       // {x, y, width, height}: the mouth region in CSS pixels of the page
  openMouthColours: kOpenMouthColours,
  frames: 0,
  ended: false,
  error: null,
  closeCode: null,
  closeReason: null,
  audio: params.get("audio") || null,
  audioPlaying: false,
  audioError: null,
  held: null,
  /// Freezes the picture at utterance time `tUs` (for screenshots and people), audio paused.
  hold(tUs) { this.held = tUs; this.drift = null; audio.pause(); },
  /// Back to following the clock.
  release() { this.held = null; },
};
window.lipsyncViewer = viewer;

// ---------------------------------------------------------------- the track as received

const track = { header: null, frames: [], summary: null };

function addBatch(batch) {
  const h = track.header;
  const nChannels = h.channels.length, nArkit = h.arkitNames.length, nVisemes = h.visemeNames.length;
  const nCoords = h.mesh ? h.mesh.vertexCount * 3 : 0;
  for (let i = 0; i < batch.tUs.length; ++i) {
    const frame = {
      t: batch.tUs[i],
      values: batch.values.slice(i * nChannels, (i + 1) * nChannels),
      arkit: batch.arkit.slice(i * nArkit, (i + 1) * nArkit),
      visemes: batch.visemeWeights.slice(i * nVisemes, (i + 1) * nVisemes),
      mesh: null,
    };
    if (nCoords && batch.meshPositions.length) {
      frame.mesh = Float32Array.from(batch.meshPositions.slice(i * nCoords, (i + 1) * nCoords));
    } else if (nCoords && batch.meshPositionsInt16) {
      const bytes = batch.meshPositionsInt16;
      const data = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
      const { quantisationScaleM: scale, quantisationOffsetM: offset } = h.mesh;
      frame.mesh = new Float32Array(nCoords);
      for (let c = 0; c < nCoords; ++c) frame.mesh[c] = offset[c % 3] + scale * data.getInt16((i * nCoords + c) * 2, true);
    }
    track.frames.push(frame);
  }
  viewer.frames = track.frames.length;
}

/// The last frame at or before `tUs` (null before the first).
function frameAt(tUs) {
  let lo = 0, hi = track.frames.length - 1, found = null;
  while (lo <= hi) {
    const mid = (lo + hi) >> 1;
    if (track.frames[mid].t <= tUs) { found = mid; lo = mid + 1; } else hi = mid - 1;
  }
  return found;
}

// ---------------------------------------------------------------- the face's geometry

let faceAsset = null;  // /face.json, for the blendshape mode
const faceAssetLoaded = fetch("/face.json").then((r) => r.json()).then((json) => {
  faceAsset = {
    rest: Float32Array.from(json.rest_um, (v) => v * 1e-6),
    triangles: json.triangles,
    parts: json.parts,
    shapes: json.blendshapes.map((s) => ({ name: s.name, deltas: Float32Array.from(s.deltas_um, (v) => v * 1e-6) })),
  };
});

let geometry = null;  // {rest, triangles, parts, colours, shapeIndex: ARKit index per shape, positions}

function buildGeometry(rest, triangles, parts, shapes) {
  const n = rest.length / 3;
  const colours = new Float32Array(n * 3), lit = new Float32Array(n);
  const lip = kOuterLip.map((id) => [rest[3 * id], rest[3 * id + 1]]);
  for (let v = 0; v < n; ++v) {
    const part = parts[v] || 0;
    let colour = kPartColours[part] || kPartColours[0];
    if (part === 0 && insidePolygon(rest[3 * v], rest[3 * v + 1], lip) && rest[3 * v + 2] > rest[3 * kUpperInnerLip + 2] - 0.004) {
      colour = kLipColour;
    }
    colours.set(colour, 3 * v);
    lit[v] = kLitParts.has(part) ? 1 : 0;
  }
  const shapeIndex = shapes.map((s) => track.header.arkitNames.indexOf(s.name));
  return { rest, triangles: Uint16Array.from(triangles), parts, colours, lit, shapes, shapeIndex,
           positions: Float32Array.from(rest), normals: new Float32Array(rest.length) };
}

function insidePolygon(x, y, polygon) {
  let inside = false;
  for (let i = 0, j = polygon.length - 1; i < polygon.length; j = i++) {
    const [xi, yi] = polygon[i], [xj, yj] = polygon[j];
    if ((yi > y) !== (yj > y) && x < ((xj - xi) * (y - yi)) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

function pose(frame) {
  const g = geometry;
  if (viewer.mode === "mesh" && frame && frame.mesh) {
    g.positions.set(frame.mesh);
  } else {
    g.positions.set(g.rest);
    if (viewer.mode === "blendshapes" && frame) {
      g.shapes.forEach((shape, k) => {
        const w = g.shapeIndex[k] >= 0 ? frame.arkit[g.shapeIndex[k]] : 0;
        if (!w) return;
        for (let c = 0; c < shape.deltas.length; ++c) g.positions[c] += w * shape.deltas[c];
      });
    }
  }
  viewer.mouthOpen = Math.round(
    (g.positions[3 * kUpperInnerLip + 1] - g.positions[3 * kLowerInnerLip + 1]) * 1e5) / 100;
}

function computeNormals(g) {
  const p = g.positions, nrm = g.normals, t = g.triangles;
  nrm.fill(0);
  for (let i = 0; i < t.length; i += 3) {
    const a = 3 * t[i], b = 3 * t[i + 1], c = 3 * t[i + 2];
    const ux = p[b] - p[a], uy = p[b + 1] - p[a + 1], uz = p[b + 2] - p[a + 2];
    const vx = p[c] - p[a], vy = p[c + 1] - p[a + 1], vz = p[c + 2] - p[a + 2];
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    for (const k of [a, b, c]) { nrm[k] += nx; nrm[k + 1] += ny; nrm[k + 2] += nz; }
  }
}

// ---------------------------------------------------------------- WebGL

const gl = canvas.getContext("webgl", { preserveDrawingBuffer: true, antialias: false });
const program = gl && makeProgram(`
  attribute vec3 position; attribute vec3 normal; attribute vec3 colour; attribute float lit;
  uniform vec3 centre; uniform vec3 scale;
  varying vec3 vColour;
  void main() {
    vec3 n = normalize(normal + vec3(0.0, 0.0, 1e-9));
    float light = 0.35 + 0.65 * abs(dot(n, normalize(vec3(0.2, 0.35, 1.0))));
    vColour = colour * mix(1.0, light, lit);
    gl_Position = vec4((position - centre) * scale, 1.0);
  }`, `
  precision mediump float; varying vec3 vColour;
  void main() { gl_FragColor = vec4(vColour, 1.0); }`);
const buffers = gl ? { position: gl.createBuffer(), normal: gl.createBuffer(), colour: gl.createBuffer(),
                       lit: gl.createBuffer(), index: gl.createBuffer() } : null;
let view = null;  // centre and scale of the orthographic front view

function makeProgram(vertexSource, fragmentSource) {
  const compile = (type, source) => {
    const shader = gl.createShader(type);
    gl.shaderSource(shader, source);
    gl.compileShader(shader);
    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(shader));
    return shader;
  };
  const p = gl.createProgram();
  gl.attachShader(p, compile(gl.VERTEX_SHADER, vertexSource));
  gl.attachShader(p, compile(gl.FRAGMENT_SHADER, fragmentSource));
  gl.linkProgram(p);
  return p;
}

function uploadStatic(g) {
  gl.bindBuffer(gl.ARRAY_BUFFER, buffers.colour);
  gl.bufferData(gl.ARRAY_BUFFER, g.colours, gl.STATIC_DRAW);
  gl.bindBuffer(gl.ARRAY_BUFFER, buffers.lit);
  gl.bufferData(gl.ARRAY_BUFFER, g.lit, gl.STATIC_DRAW);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buffers.index);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, g.triangles, gl.STATIC_DRAW);
  // Front view of the skin's bounding box with a margin; z mapped into the clip range (near = +z).
  const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
  for (let v = 0; v < g.rest.length / 3; ++v) {
    if (g.parts[v]) continue;
    for (let a = 0; a < 3; ++a) { min[a] = Math.min(min[a], g.rest[3 * v + a]); max[a] = Math.max(max[a], g.rest[3 * v + a]); }
  }
  const half = [0, 1, 2].map((a) => (max[a] - min[a]) / 2);
  const fit = 0.92 / Math.max(half[0] * canvas.height / canvas.width, half[1]);
  view = { centre: [0, 1, 2].map((a) => (min[a] + max[a]) / 2),
           scale: [fit * canvas.height / canvas.width, fit, -0.5 / (half[2] + 0.05)] };
  // The mouth region on the page: the outer lip contour at rest, widened for the jaw's drop.
  const xs = kOuterLip.map((id) => g.rest[3 * id]), ys = kOuterLip.map((id) => g.rest[3 * id + 1]);
  const toPixel = (x, y) => [((x - view.centre[0]) * view.scale[0] + 1) / 2 * canvas.clientWidth,
                             (1 - (y - view.centre[1]) * view.scale[1]) / 2 * canvas.clientHeight];
  const [left, top] = toPixel(Math.min(...xs), Math.max(...ys) + 0.003);
  const [right, bottom] = toPixel(Math.max(...xs), Math.min(...ys) - 0.012);
  const box = canvas.getBoundingClientRect();
  viewer.mouthRect = { x: Math.round(box.left + window.scrollX + left), y: Math.round(box.top + window.scrollY + top),
                       width: Math.round(right - left), height: Math.round(bottom - top) };
}

function draw() {
  if (!gl || !geometry) return;
  computeNormals(geometry);
  gl.viewport(0, 0, canvas.width, canvas.height);
  gl.clearColor(0.875, 0.89, 0.91, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.enable(gl.DEPTH_TEST);
  gl.useProgram(program);
  const attribute = (name, buffer, data, size) => {
    const location = gl.getAttribLocation(program, name);
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    if (data) gl.bufferData(gl.ARRAY_BUFFER, data, gl.DYNAMIC_DRAW);
    gl.enableVertexAttribArray(location);
    gl.vertexAttribPointer(location, size, gl.FLOAT, false, 0, 0);
  };
  attribute("position", buffers.position, geometry.positions, 3);
  attribute("normal", buffers.normal, geometry.normals, 3);
  attribute("colour", buffers.colour, null, 3);
  attribute("lit", buffers.lit, null, 1);
  gl.uniform3fv(gl.getUniformLocation(program, "centre"), view.centre);
  gl.uniform3fv(gl.getUniformLocation(program, "scale"), view.scale);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buffers.index);
  gl.drawElements(gl.TRIANGLES, geometry.triangles.length, gl.UNSIGNED_SHORT, 0);
}

// ---------------------------------------------------------------- readouts

let bars = [];

function makeBars(names) {
  elements.bars.textContent = "";
  bars = names.map((name) => {
    const row = document.createElement("div");
    row.className = "bar";
    row.innerHTML = '<span></span><span class="track"><span class="fill"></span></span>';
    row.firstChild.textContent = name;
    elements.bars.appendChild(row);
    return { fill: row.querySelector(".fill"), peak: 1e-6 };
  });
}

function showReadouts(frame) {
  viewer.frameTime = frame ? frame.t : null;
  elements["frame-time"].textContent = frame ? String(frame.t) + " µs" : "–";
  const h = track.header;
  let viseme = null;
  if (frame && frame.visemes.length) {
    let best = 0;
    frame.visemes.forEach((w, i) => { if (w > frame.visemes[best]) best = i; });
    viseme = h.visemeNames[best];
  }
  viewer.viseme = viseme;
  elements.viseme.textContent = viseme ?? "–";
  elements.drift.textContent = viewer.drift === null ? "–" : (viewer.drift / 1000).toFixed(1) + " ms";
  const values = frame ? (frame.values.length ? frame.values : frame.arkit) : [];
  bars.forEach((bar, i) => {
    const v = Math.abs(values[i] || 0);
    bar.peak = Math.max(bar.peak, v, 1);
    bar.fill.style.width = (100 * v / bar.peak).toFixed(1) + "%";
  });
}

function setStatus(text, isError) {
  elements.status.textContent = text;
  elements.status.className = isError ? "error" : "";
}

// ---------------------------------------------------------------- audio slaved to the anchor

// After a start or a seek: the position it aimed at; drift is measured again only once the audio
// has moved past it (its pipeline runs again) and kSettleAfterStartMs more.
let audioRestart = null;  // {fromS, runningSinceMs}
let audioInBand = 0;      // consecutive measurements within kLockUs while not locked
let audioLeadUs = 0;  // how far ahead of the anchor a seek aims (the pipeline's restart lag)
let audioStarting = false;

function steerAudio(nowUs) {
  if (!viewer.audio || viewer.held !== null || nowUs === null) return;
  const duration = audio.duration;
  if (nowUs < 0 || !(duration > 0) || nowUs / 1e6 >= duration) {
    viewer.audioPlaying = false;
    if (!audio.paused && nowUs / 1e6 >= duration) audio.pause();
    return;
  }
  if (audio.paused) {
    if (audioStarting || audio.ended) return;
    audioStarting = true;
    viewer.locked = false;
    audioInBand = 0;
    audio.currentTime = (nowUs + audioLeadUs) / 1e6;
    audioRestart = { fromS: audio.currentTime, runningSinceMs: null };
    audio.playbackRate = 1;
    audio.play()
      .catch((e) => { viewer.audioError = e.message; setStatus("audio: " + e.message + " (click the page to allow it)", true); })
      .finally(() => { audioStarting = false; });
    return;
  }
  viewer.audioPlaying = true;
  if (audioRestart) {
    if (audio.seeking || audio.currentTime <= audioRestart.fromS) return;
    audioRestart.runningSinceMs ??= performance.now();
    if (performance.now() - audioRestart.runningSinceMs < kSettleAfterStartMs) return;
    audioRestart = null;
  }
  const drift = Math.round(audio.currentTime * 1e6 - nowUs);
  viewer.drift = drift;
  viewer.driftSamples += 1;
  const trim = Math.max(-kMaxRateTrim, Math.min(kMaxRateTrim, (drift / 1e6) * kRateGainPerSecond));
  audio.playbackRate = 1 - trim;
  if (viewer.locked) {
    if (Math.abs(drift) > kResyncUs) {
      seekAudio(nowUs, drift);
      return;
    }
    viewer.maxAbsDrift = Math.max(viewer.maxAbsDrift ?? 0, Math.abs(drift));
    viewer.lockedDrifts.push(Math.abs(drift));
    if (viewer.lockedDrifts.length > 1000) viewer.lockedDrifts.shift();
    viewer.lockedSamples += 1;
    return;
  }
  if (Math.abs(drift) > kSeekUnlockedUs) {
    seekAudio(nowUs, drift);
    return;
  }
  audioInBand = Math.abs(drift) < kLockUs ? audioInBand + 1 : 0;
  if (audioInBand >= kLockSamples) {
    viewer.locked = true;
    viewer.lockedAtUs = nowUs;
  }
}

/// A start or a seek costs the media pipeline a restart, which the audio spends behind the anchor:
/// seek ahead by the lag measured after the last one, so that it lands on the anchor.
function seekAudio(nowUs, drift) {
  audioLeadUs = Math.max(0, Math.min(kMaxLeadUs, audioLeadUs - drift));
  audio.currentTime = (nowUs + audioLeadUs) / 1e6;
  audioRestart = { fromS: audio.currentTime, runningSinceMs: null };
  viewer.resyncs += 1;
  viewer.locked = false;
  audioInBand = 0;
}

// ---------------------------------------------------------------- the loop

function utteranceNowUs() {
  if (viewer.held !== null) return viewer.held;
  if (viewer.utteranceZeroUs === null) return null;
  return Math.round((performance.timeOrigin + performance.now()) * 1000 - viewer.utteranceZeroUs);
}

let drawn = { geometry: null, frameIndex: undefined };

/// Every animation frame: the frame for the current utterance time, drawn when it changed.
function tick() {
  const now = utteranceNowUs();
  viewer.utteranceTime = now;
  if (track.header && geometry) {
    const index = now === null || now < 0 ? null : frameAt(now);
    viewer.frameIndex = index;
    const frame = index === null ? null : track.frames[index];
    if (drawn.geometry !== geometry || drawn.frameIndex !== index) {
      pose(frame);
      draw();
      drawn = { geometry, frameIndex: index };
    }
    showReadouts(frame);
  }
  requestAnimationFrame(tick);
}

// The audio is steered on a timer of its own: a page that draws slowly (software WebGL on a busy
// machine) still measures and corrects its drift every kSteerIntervalMs.
setInterval(() => { if (track.header) steerAudio(utteranceNowUs()); }, kSteerIntervalMs);

// ---------------------------------------------------------------- the WebSocket

function onHeader(header) {
  viewer.waiting = false;
  if (viewer.audio && audio.ended) audio.currentTime = 0;  // a new track: the audio may play again
  setStatus("following " + header.session);
  track.header = header;
  track.frames = [];
  track.summary = null;
  const anchor = header.mediaClock;
  if (anchor && anchor.clock === "unix" && anchor.utteranceZeroUs) {
    viewer.clock = "unix";
    viewer.utteranceZeroUs = anchor.utteranceZeroUs;
  } else {
    viewer.clock = "arrival";
    viewer.utteranceZeroUs = Math.round((performance.timeOrigin + performance.now()) * 1000);
  }
  if (header.mesh && header.mesh.vertexCount) {
    viewer.mode = "mesh";
    geometry = buildGeometry(Float32Array.from(header.mesh.restPositions), header.mesh.triangles, header.mesh.parts, []);
  } else {
    viewer.mode = header.arkitNames.length ? "blendshapes" : "rest";
    geometry = buildGeometry(faceAsset.rest, faceAsset.triangles, faceAsset.parts, faceAsset.shapes);
  }
  if (gl) uploadStatic(geometry);
  elements.mode.textContent = viewer.mode === "mesh" ? "server mesh (" + header.mesh.vertexCount + " vertices)"
    : viewer.mode === "blendshapes" ? "ARKit blendshapes" : "rest (no face outputs)";
  makeBars(header.channels.length ? header.channels : header.arkitNames);
}

function connect(session) {
  const start = params.get("start");
  const url = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws?session=" +
    encodeURIComponent(session) + (start ? "&start=" + encodeURIComponent(start) : "") +
    (apiKey ? "&key=" + encodeURIComponent(apiKey) : "");
  const socket = new WebSocket(url);
  socket.binaryType = "arraybuffer";
  elements.session.textContent = session;
  setStatus("connecting to " + session);
  socket.onopen = () => { viewer.connected = true; };
  socket.onmessage = (event) => {
    if (typeof event.data === "string") {  // the error before the close: {"code", "message"}
      const error = JSON.parse(event.data);
      if (error.code === "NOT_FOUND" && !track.header) return;  // waited for (onclose)
      viewer.error = error.code + ": " + error.message;
      setStatus(viewer.error, true);
      return;
    }
    const message = decodeTrackMessage(new Uint8Array(event.data));
    if (message.header) onHeader(message.header);
    if (message.frames && track.header) addBatch(message.frames);
    if (message.summary) {
      track.summary = message.summary;
      viewer.ended = true;
      setStatus(session + ": complete, " + message.summary.frames + " frames");
    }
  };
  socket.onclose = (event) => {
    viewer.connected = false;
    viewer.closeCode = event.code;
    viewer.closeReason = event.reason;
    if (event.code === kNotFoundCloseCode && !track.header) {
      // Opened before its producer: wait for the session to start.
      viewer.waiting = true;
      viewer.error = null;
      setStatus("waiting for session " + session + " to start");
      setTimeout(() => connect(session), kRetryNotFoundMs);
      return;
    }
    viewer.waiting = false;
    if (event.code !== 1000 && !viewer.error) {
      viewer.error = "closed (" + event.code + ")" + (event.reason ? ": " + event.reason : "");
      setStatus(viewer.error, true);
    }
  };
}

// ---------------------------------------------------------------- the page's forms

function navigate(session, audioUrl) {
  const next = new URLSearchParams();
  if (session) next.set("session", session);
  if (audioUrl) next.set("audio", audioUrl);
  if (apiKey) next.set("key", apiKey);
  location.search = next.toString();
}

document.getElementById("follow-form").addEventListener("submit", (event) => {
  event.preventDefault();
  navigate(document.getElementById("session-input").value.trim(), document.getElementById("audio-input").value.trim());
});

document.getElementById("audio-file").addEventListener("change", (event) => {
  const file = event.target.files[0];
  if (!file) return;
  audio.src = URL.createObjectURL(file);
  viewer.audio = file.name;
});

document.getElementById("try-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  const query = new URLSearchParams();
  const session = document.getElementById("session-input").value.trim();
  if (session) query.set("session", session);
  if (document.getElementById("try-mesh").checked) query.set("mesh", "1");
  if (apiKey) query.set("key", apiKey);
  const response = await fetch("/sessions?" + query.toString(),
                               { method: "POST", body: document.getElementById("try-text").value });
  const answer = await response.json();
  if (!response.ok) {
    elements["try-result"].textContent = answer.code + ": " + answer.message;
    return;
  }
  navigate(answer.session, viewer.audio && !viewer.audio.startsWith("blob:") ? params.get("audio") : "");
});

if (viewer.audio) audio.src = viewer.audio;
document.getElementById("session-input").value = viewer.session || "";
document.getElementById("audio-input").value = viewer.audio || "";
document.addEventListener("click", () => { if (viewer.audioError) { viewer.audioError = null; audio.play().catch(() => {}); } });
if (!gl) setStatus("this browser has no WebGL: readouts only", true);

faceAssetLoaded.then(() => {
  if (viewer.session) connect(viewer.session);
  else setStatus("no session: name one, or paste phonemes for a quick try");
  requestAnimationFrame(tick);
});
