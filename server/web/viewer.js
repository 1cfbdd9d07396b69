// lipsyncd's browser viewer (docs/viewer.md). It follows one session over the WebSocket /ws (each
// binary message a serialised TrackMessage, decoded by track_decoder.js; lipsyncd waits up to
// ?wait=S for a session that has not started, and the status line counts the seconds) and draws the
// track's frame for the current utterance time, at each animation frame while the picture can
// change on its own; after the track's end the face eases back to rest, and the page then draws
// nothing (and suspends its audio) until a message, hold() or release() wakes it:
//
// - Time. The header's media-clock anchor says when utterance time 0 plays. On the "unix" clock
//   (the producer's wall clock; lipsyncd's quick try uses it) the page shows frame t at wall time
//   utterance_zero_us + t, so every viewer of a session shows the same frame at the same moment.
//   With another clock, or none, the page starts utterance time 0 when the header arrives.
// - Audio. An audio file or URL (?audio=URL, a file chosen on the page, or, for a Speak session,
//   lipsyncd's own /audio?session=NAME) is fetched whole, decoded, and played on the Web Audio
//   clock: an AudioBufferSourceNode started at the context time whose sample leaves the speakers
//   when the anchor plays that buffer position (getOutputTimestamp). Every kSteerIntervalMs the
//   sound leaving the speakers is compared with the anchor's time on screen (the drift, #drift);
//   a small drift is trimmed by the playback rate, a large one rescheduled. No byte ranges are
//   needed. A cross-origin URL the page may not read (no CORS header) falls back to the <audio>
//   element, steered by seeks (it needs byte ranges). The face follows the anchor, not the audio,
//   so that a stalled or missing audio never freezes the face.
// - The face. With the mesh output (the header carries a MeshTopology) the page draws the server's
//   simulated vertices. Otherwise it poses the viewer's face (/face.json, data/face/
//   viewer_face.json: the physics face fitted as ARKit blendshapes by tools/face/make_viewer_face)
//   with the frame's ARKit weights: rest + Σ w_k Δ_k. In both modes the lips are closed at rest
//   (restClosure: the physics face's rest, the canonical mesh's, has them 5.5 mm apart).
//   Skin and lips are lit, the skin painted from landmark contours (lips, eyes, brows) in a
//   texture laid on the rest pose; the mouth cavity, teeth and tongue are drawn in flat colours
//   (kOpenMouthColours) so an open mouth can be measured on a screenshot.
//
// Its state is on window.lipsyncViewer and in the elements #frame-time (µs), #viseme and #drift.
"use strict";

// The Web Audio path (the default: the whole file decoded, scheduled on the AudioContext's clock).
const kScheduleAheadS = 0.1;     // a (re)schedule starts the sound this far ahead of the context's time
const kRescheduleUs = 25000;     // |drift| beyond this, kRescheduleSamples times in a row: rescheduled
const kRescheduleSamples = 3;
const kMaxRateTrim = 0.01;       // playback-rate trim of a small drift (1 %: a sixth of a semitone)
const kCrossfadeS = 0.005;       // a rescheduled sound fades in over this while the old one fades out
// Both paths: kLockSamples measurements in a row within kLockUs lock the audio.
const kLockUs = 30000;
const kLockSamples = 5;
const kRateGainPerSecond = 4;   // playback-rate trim per second of drift
const kSteerIntervalMs = 20;
// The <audio> element's fallback (cross-origin audio the page may not read).
const kResyncUs = 100000;       // locked audio further than this from the anchor is seeked
const kSeekUnlockedUs = 60000;  // a started or seeked audio further than this is seeked again
const kSeekSamples = 3;         // ... kSeekSamples measurements in a row (one is the element's jitter)
const kMaxLeadUs = 500000;
const kMaxElementRateTrim = 0.15;
const kReturnToRestUs = 250000; // after the track's end the face eases back to rest over this
const kSettleAfterStartMs = 60; // after a start or seek, drift is measured once the audio runs again, and this long after
const kWaitForSessionS = 120;   // lipsyncd waits this long for a session that has not started (?wait=S)
const kMaxWaitS = 3600;

// Mesh parts (lipsync.v1.MeshPart) and their colours, linear-ish RGB 0..1.
const kPartColours = [
  [0.87, 0.70, 0.60],  // skin (lit)
  [0.72, 0.36, 0.38],  // inner lip (lit)
  [0.20, 0.02, 0.12],  // mouth cavity (flat)
  [0.96, 0.95, 0.88],  // upper teeth (flat)
  [0.96, 0.95, 0.88],  // lower teeth (flat)
  [0.85, 0.30, 0.40],  // tongue (flat)
  [0.93, 0.92, 0.88],  // eye white (lit: the physics face's eyeballs)
  [0.36, 0.24, 0.14],  // iris (lit)
  [0.03, 0.03, 0.03],  // pupil (flat)
];
const kLipColour = [0.76, 0.42, 0.44];  // the vermilion, painted inside kOuterLip
const kLitParts = new Set([0, 1, 6, 7]);
/// What an open mouth shows on a screenshot (8-bit sRGB as drawn): cavity, teeth, tongue.
const kOpenMouthColours = [2, 3, 5].map((p) => kPartColours[p].map((c) => Math.round(c * 255)));
// Landmark contours of the MediaPipe canonical face mesh (vertex ids): the skin is painted from
// them in the rest pose's x-y plane (a texture), so the paint follows the face as it moves and its
// edges are those of the contours, however large the mesh's triangles are.
// Outer lip contour: the vermilion (lip colour) inside it.
const kOuterLip = [61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291, 375, 321, 405, 314, 17, 84, 181, 91, 146];
// Eye contours, the upper lid first (corner to corner), then the lower lid back.
const kEyes = [[33, 246, 161, 160, 159, 158, 157, 173, 133, 155, 154, 153, 145, 144, 163, 7],
               [263, 466, 388, 387, 386, 385, 384, 398, 362, 382, 381, 380, 374, 373, 390, 249]];
const kUpperLidPoints = 9;
// Eyebrows: the upper edge, then the lower edge back.
const kBrows = [[70, 63, 105, 66, 107, 55, 65, 52, 53, 46], [300, 293, 334, 296, 336, 285, 295, 282, 283, 276]];
const kPaintTexels = 512;   // the paint texture's side (3.4 texels per mm)
const kIrisRadiusM = 0.0056, kPupilRadiusM = 0.0022;
// The relaxed rest (both modes): the physics face's lips are 5.5 mm apart at rest, in the server's
// simulated mesh and in the fitted blendshapes (its teeth show). The page closes them with a
// displacement of the lips toward each other (kRestClosure*), in full while the gap is at most its
// rest value, fading out as the mouth opens further (gone at kRestClosureFadeGaps times the rest
// gap), so that an /aa/ opens nearly as far and a closed /p b m/ stays as it is.
const kRestClosureFadeGaps = 4;
const kRestClosureLipHeightM = 0.008;  // moved in full within this of the lip line, fading to 0 at 3x
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
  waiting: false,        // the session has not started yet: lipsyncd waits for it (until waitingUntilMs)
  waitingUntilMs: null,  // performance.now() when lipsyncd stops waiting
  session: params.get("session") || null,
  mode: null,            // "mesh", "blendshapes" or "rest" (no face data in the stream)
  clock: null,           // "unix" (the anchor's) or "arrival"
  utteranceZeroUs: null, // the anchor
  frameTime: null,       // µs of the frame on screen
  frameIndex: null,
  viseme: null,
  drift: null,           // µs: the sound leaving the speakers − the anchor's time on screen (null: none plays)
  locked: false,         // the audio reached the anchor (|drift| < kLockUs) since its last (re)schedule
  lockedAtUs: null,      // utterance time when it did
  maxAbsDrift: null,     // µs, over the measurements while locked
  lockedDrifts: [],      // µs, |drift| of the last 1,000 measurements while locked
  driftSamples: 0,
  lockedSamples: 0,      // measurements while locked
  resyncs: 0,            // reschedules (Web Audio) or seeks (element) after the start
  audioPath: null,       // "webaudio" (decoded, on the AudioContext's clock) or "element" (the fallback)
  audioContextState: null,
  audioNote: null,       // why the audio plays through the <audio> element (the fallback), if it does
  audioLoadedAtMs: null, // performance.now() when the audio was decoded
  audioDurationUs: null,
  audioStartedAtUs: null, // utterance time of the first drift measured (the audio heard)
  audioStartOffsetUs: null, // µs into the audio where its first schedule started it (0: from its first sample)
  audioClock: null,      // "timestamp" (getOutputTimestamp) or "latency" (currentTime + latencies)
  lastClock: null,       // the last measurement: context and performance times, position, utterance time
  mouthOpen: null,       // mm between the inner lips (landmarks 13 and 14) on screen
  mouthRect: null,       // {x, y, width, height}: the mouth region in CSS pixels of the page
  openMouthColours: kOpenMouthColours,
  frames: 0,
  framesDrawn: 0,        // pictures drawn (a new frame on screen), for the frame rate
  animating: false,      // the page draws at every animation frame (false: idle until something changes)
  ended: false,
  error: null,
  closeCode: null,
  closeReason: null,
  socket: null,          // the follower's WebSocket (/ws)
  audio: params.get("audio") || null,
  audioPlaying: false,
  audioError: null,
  held: null,
  /// Freezes the picture at utterance time `tUs` (for screenshots and people), audio paused.
  hold(tUs) { this.held = tUs; this.drift = null; audio.pause(); if (sound.context) stopSound(); wake(); },
  /// Back to following the clock.
  release() { this.held = null; wake(); },
  /// µs now on the anchor's timeline (the held time while held; null before a header).
  get utteranceTime() { return utteranceNowUs(); },
  /// Where the face's outer lip contour and eye contours are on the page now (CSS pixels).
  contours() { return { lip: onPage(kOuterLip), eyes: kEyes.map(onPage) }; },
  /// Per frame received: [t µs, the viseme the page shows for it (the server's event), the largest weight's].
  visemes() {
    const names = track.header ? track.header.visemeNames : [];
    return track.frames.map((f) => [f.t, f.viseme === null ? null : names[f.viseme],
      f.visemes.length ? names[f.visemes.indexOf(Math.max(...f.visemes))] : null]);
  },
};
window.lipsyncViewer = viewer;

// ---------------------------------------------------------------- the track as received

// eventViseme: the viseme of the server's last VisemeEvent (null before the first), which each
// frame keeps as `viseme`: the page shows the server's events, not its own reading of the weights
// (they differ where the server holds a closure's viseme on its key frames).
const track = { header: null, frames: [], summary: null, closed: false, eventViseme: null };

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
      viseme: null,
      mesh: null,
    };
    for (const event of batch.visemeEvents) if (event.startUs === frame.t) track.eventViseme = event.viseme;
    frame.viseme = track.eventViseme;
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
  const colours = new Float32Array(n * 3), lit = new Float32Array(n), painted = new Float32Array(n);
  for (let v = 0; v < n; ++v) {
    const part = parts[v] || 0;
    colours.set(kPartColours[part] || kPartColours[0], 3 * v);
    lit[v] = kLitParts.has(part) ? 1 : 0;
    painted[v] = part === 0 ? 1 : 0;
  }
  const shapeIndex = shapes.map((s) => track.header.arkitNames.indexOf(s.name));
  const box = skinBox(rest, parts);
  const uv = new Float32Array(2 * n);
  for (let v = 0; v < n; ++v) {
    uv[2 * v] = (rest[3 * v] - box.min[0]) / (box.max[0] - box.min[0]);
    uv[2 * v + 1] = (box.max[1] - rest[3 * v + 1]) / (box.max[1] - box.min[1]);  // the texture's rows go down
  }
  return { rest, triangles: Uint16Array.from(triangles), parts, colours, lit, painted, uv, box, shapes, shapeIndex,
           closure: restClosure(rest, parts),
           positions: Float32Array.from(rest), normals: new Float32Array(rest.length) };
}

/// The skin's bounding box at rest (metres).
function skinBox(rest, parts) {
  const min = [Infinity, Infinity, Infinity], max = [-Infinity, -Infinity, -Infinity];
  for (let v = 0; v < rest.length / 3; ++v) {
    if (parts[v]) continue;
    for (let a = 0; a < 3; ++a) { min[a] = Math.min(min[a], rest[3 * v + a]); max[a] = Math.max(max[a], rest[3 * v + a]); }
  }
  return { min, max };
}

/// The displacement that closes the rest pose's lips (y only; skin and inner lips): the upper lip
/// down and the lower lip up by half the rest gap each, in full near the lip line and between the
/// mouth corners, fading out toward the nose, the chin and the cheeks.
function restClosure(rest, parts) {
  const yUpper = rest[3 * kUpperInnerLip + 1], yLower = rest[3 * kLowerInnerLip + 1];
  const half = (yUpper - yLower) / 2, lineY = (yUpper + yLower) / 2;
  const cornerX = Math.abs(rest[3 * kOuterLip[0]]);
  const smooth = (t) => { const c = Math.max(0, Math.min(1, t)); return c * c * (3 - 2 * c); };
  const closure = new Float32Array(rest.length);
  if (!(half > 0)) return { vector: closure, gapM: 0 };  // the physics face rests closed (issue 41)
  for (let v = 0; v < rest.length / 3; ++v) {
    if (parts[v] > 1) continue;  // cavity, teeth, tongue and eyes stay
    const dy = rest[3 * v + 1] - lineY;
    const across = smooth((1.3 * cornerX - Math.abs(rest[3 * v])) / (0.5 * cornerX));
    const along = smooth((3 * kRestClosureLipHeightM - Math.abs(dy)) / (2 * kRestClosureLipHeightM));
    closure[3 * v + 1] = -Math.sign(dy) * half * Math.min(1, Math.abs(dy) / half) * across * along;
  }
  return { vector: closure, gapM: 2 * half };
}

/// The paint of the skin (RGBA pixels), in the rest pose's x-y plane: the vermilion inside the outer lip contour,
/// the eyes (white, iris, pupil, a lid shadow and lash line) inside the eye contours, the brows.
function paintTexture(rest, box) {
  const canvas2d = document.createElement("canvas");
  canvas2d.width = canvas2d.height = kPaintTexels;
  const c = canvas2d.getContext("2d", { willReadFrequently: true });  // a CPU canvas: read once for the texture
  const scaleX = kPaintTexels / (box.max[0] - box.min[0]), scaleY = kPaintTexels / (box.max[1] - box.min[1]);
  const at = (id) => [(rest[3 * id] - box.min[0]) * scaleX, (box.max[1] - rest[3 * id + 1]) * scaleY];
  const path = (ids, from = 0, to = ids.length) => {
    c.beginPath();
    ids.slice(from, to).forEach((id, i) => { const [x, y] = at(id); if (i) c.lineTo(x, y); else c.moveTo(x, y); });
  };
  const rgb = (colour, alpha = 1) => `rgba(${colour.map((v) => Math.round(v * 255)).join(",")},${alpha})`;
  const mm = scaleX / 1000;
  // Lips: exactly the outer contour (its edge anti-aliased).
  path(kOuterLip);
  c.closePath();
  c.fillStyle = rgb(kLipColour);
  c.fill();
  // Brows.
  for (const brow of kBrows) {
    path(brow);
    c.closePath();
    c.fillStyle = "rgba(92,66,50,0.85)";
    c.fill();
  }
  for (const eye of kEyes) {
    const points = eye.map(at);
    const xs = points.map((p) => p[0]), ys = points.map((p) => p[1]);
    const centre = [(Math.min(...xs) + Math.max(...xs)) / 2, (Math.min(...ys) + Math.max(...ys)) / 2 + 0.4 * mm];
    c.save();
    path(eye);
    c.closePath();
    c.clip();
    c.fillStyle = "rgb(236,232,226)";
    c.fill();
    const iris = c.createRadialGradient(centre[0], centre[1], kPupilRadiusM * 1000 * mm, centre[0], centre[1], kIrisRadiusM * 1000 * mm);
    iris.addColorStop(0, "rgb(96,72,48)");
    iris.addColorStop(1, "rgb(58,42,30)");
    c.fillStyle = iris;
    c.beginPath();
    c.arc(centre[0], centre[1], kIrisRadiusM * 1000 * mm, 0, 2 * Math.PI);
    c.fill();
    c.fillStyle = "rgb(16,12,12)";
    c.beginPath();
    c.arc(centre[0], centre[1], kPupilRadiusM * 1000 * mm, 0, 2 * Math.PI);
    c.fill();
    c.fillStyle = "rgba(255,255,255,0.85)";
    c.beginPath();
    c.arc(centre[0] - 1.2 * mm, centre[1] - 1.2 * mm, 0.7 * mm, 0, 2 * Math.PI);
    c.fill();
    // The upper lid's shadow on the eye.
    path(eye, 0, kUpperLidPoints);
    c.strokeStyle = "rgba(60,40,32,0.6)";
    c.lineWidth = 1.6 * mm;
    c.stroke();
    c.restore();
    // Lash line along the upper lid, a thinner line along the lower.
    path(eye, 0, kUpperLidPoints);
    c.strokeStyle = "rgb(40,28,24)";
    c.lineWidth = 0.9 * mm;
    c.lineJoin = c.lineCap = "round";
    c.stroke();
    path([...eye.slice(kUpperLidPoints - 1), eye[0]]);
    c.strokeStyle = "rgba(120,80,66,0.7)";
    c.lineWidth = 0.4 * mm;
    c.stroke();
  }
  return c.getImageData(0, 0, kPaintTexels, kPaintTexels);
}

/// The face of `frame` (the rest pose for null), its displacement from the rest scaled by `amount`
/// (1: the frame as it is; less while the face eases back to rest after the track's end).
function pose(frame, amount = 1) {
  const g = geometry;
  g.positions.set(g.rest);
  if (viewer.mode === "mesh" && frame && frame.mesh) {
    if (amount === 1) g.positions.set(frame.mesh);
    else for (let c = 0; c < g.positions.length; ++c) g.positions[c] += amount * (frame.mesh[c] - g.rest[c]);
  } else if (viewer.mode === "blendshapes" && frame) {
    g.shapes.forEach((shape, k) => {
      const w = g.shapeIndex[k] >= 0 ? amount * frame.arkit[g.shapeIndex[k]] : 0;
      if (!w) return;
      for (let c = 0; c < shape.deltas.length; ++c) g.positions[c] += w * shape.deltas[c];
    });
  }
  if (g.closure.gapM > 0) {  // the relaxed rest: lips together while the face holds them at most as far apart as at rest
    const gap = g.positions[3 * kUpperInnerLip + 1] - g.positions[3 * kLowerInnerLip + 1], rest = g.closure.gapM;
    const amount = gap <= rest ? Math.max(0, gap / rest)
                               : Math.max(0, (kRestClosureFadeGaps * rest - gap) / ((kRestClosureFadeGaps - 1) * rest));
    const closure = g.closure.vector;
    if (amount > 0) for (let c = 1; c < closure.length; c += 3) g.positions[c] += amount * closure[c];
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

const gl = canvas.getContext("webgl", { antialias: false });
const program = gl && makeProgram(`
  attribute vec3 position; attribute vec3 normal; attribute vec3 colour; attribute float lit;
  attribute vec2 uv; attribute float painted;
  uniform vec3 centre; uniform vec3 scale;
  varying vec3 vColour; varying float vLight; varying vec2 vUv; varying float vPainted;
  void main() {
    vec3 n = normalize(normal + vec3(0.0, 0.0, 1e-9));
    float light = 0.35 + 0.65 * abs(dot(n, normalize(vec3(0.2, 0.35, 1.0))));
    vColour = colour;
    vLight = mix(1.0, light, lit);
    vUv = uv;
    vPainted = painted;
    gl_Position = vec4((position - centre) * scale, 1.0);
  }`, `
  precision mediump float;
  varying vec3 vColour; varying float vLight; varying vec2 vUv; varying float vPainted;
  uniform sampler2D paint;
  void main() {
    vec4 p = texture2D(paint, vUv);
    gl_FragColor = vec4(mix(vColour, p.rgb, p.a * vPainted) * vLight, 1.0);
  }`);
const buffers = gl ? { position: gl.createBuffer(), normal: gl.createBuffer(), colour: gl.createBuffer(),
                       lit: gl.createBuffer(), uv: gl.createBuffer(), painted: gl.createBuffer(),
                       index: gl.createBuffer(), paint: gl.createTexture() } : null;
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
  gl.bindBuffer(gl.ARRAY_BUFFER, buffers.uv);
  gl.bufferData(gl.ARRAY_BUFFER, g.uv, gl.STATIC_DRAW);
  gl.bindBuffer(gl.ARRAY_BUFFER, buffers.painted);
  gl.bufferData(gl.ARRAY_BUFFER, g.painted, gl.STATIC_DRAW);
  gl.bindTexture(gl.TEXTURE_2D, buffers.paint);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, paintTexture(g.rest, g.box));
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, buffers.index);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, g.triangles, gl.STATIC_DRAW);
  // Front view of the skin's bounding box with a margin; z mapped into the clip range (near = +z).
  const { min, max } = g.box;
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

/// Landmarks `ids` of the pose drawn, in CSS pixels of the page: [[x, y], ...].
function onPage(ids) {
  if (!geometry || !view) return null;
  const box = canvas.getBoundingClientRect();
  return ids.map((id) => [
    box.left + window.scrollX + ((geometry.positions[3 * id] - view.centre[0]) * view.scale[0] + 1) / 2 * canvas.clientWidth,
    box.top + window.scrollY + (1 - (geometry.positions[3 * id + 1] - view.centre[1]) * view.scale[1]) / 2 * canvas.clientHeight]);
}

function draw() {
  if (!gl || !geometry) return;
  viewer.framesDrawn += 1;
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
  attribute("uv", buffers.uv, null, 2);
  attribute("painted", buffers.painted, null, 1);
  gl.activeTexture(gl.TEXTURE0);
  gl.bindTexture(gl.TEXTURE_2D, buffers.paint);
  gl.uniform1i(gl.getUniformLocation(program, "paint"), 0);
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
    return { fill: row.querySelector(".fill"), peak: 1e-6, width: null };
  });
}

/// Sets an element's text only when it changes (a write costs the page a layout).
function setText(element, text) {
  if (element.textContent !== text) element.textContent = text;
}

function showReadouts(frame) {
  viewer.frameTime = frame ? frame.t : null;
  setText(elements["frame-time"], frame ? String(frame.t) + " µs" : "–");
  const h = track.header;
  let viseme = null;
  if (frame && frame.viseme !== null) {
    viseme = h.visemeNames[frame.viseme];  // the server's event
  } else if (frame && frame.visemes.length) {
    // Only before the first event (a follower that joined from now): the largest weight, as the server picks it.
    let best = 0;
    frame.visemes.forEach((w, i) => { if (w > frame.visemes[best]) best = i; });
    viseme = h.visemeNames[best];
  }
  viewer.viseme = viseme;
  setText(elements.viseme, viseme ?? "–");
  setText(elements.drift, viewer.drift === null ? "–" : (viewer.drift / 1000).toFixed(1) + " ms");
  const values = frame ? (frame.values.length ? frame.values : frame.arkit) : [];
  bars.forEach((bar, i) => {
    const v = Math.abs(values[i] || 0);
    bar.peak = Math.max(bar.peak, v, 1);
    const width = (100 * v / bar.peak).toFixed(1) + "%";
    if (bar.width !== width) bar.fill.style.width = bar.width = width;
  });
}

// The status line: what the page follows (connecting, waiting, following, complete, an error),
// then what went wrong with the audio or why it plays as it does, each kept until its own next news.
const statusLine = { session: "", sessionError: false, audio: null, audioError: false };

function setStatus(text, isError) {
  statusLine.session = text;
  statusLine.sessionError = !!isError;
  showStatus();
}

/// The audio's part of the status line ("audio: …"); null clears it.
function setAudioStatus(text, isError = true) {
  statusLine.audio = text;
  statusLine.audioError = !!(text && isError);
  showStatus();
}

function showStatus() {
  const { session, audio } = statusLine;
  elements.status.textContent = audio === null ? session : (session ? session + "; " : "") + "audio: " + audio;
  elements.status.className = statusLine.sessionError || statusLine.audioError ? "error" : "";
}

// ---------------------------------------------------------------- audio on the Web Audio clock

// The whole file is fetched and decoded (no byte ranges needed) and played by an
// AudioBufferSourceNode scheduled on the AudioContext's clock: started at the context time whose
// sample leaves the speakers when the anchor says that buffer position plays. The context's
// getOutputTimestamp() pairs a context time with the performance.now() at which that sample
// reaches the output (its latency included); before it has one, currentTime plus baseLatency and
// outputLatency stand in. Every kSteerIntervalMs the page reads where the sound leaving the
// speakers is in the buffer and compares it with the anchor's utterance time at that instant
// (what the screen shows): the drift. A small drift is trimmed by the source's playback rate
// (at most kMaxRateTrim); beyond kRescheduleUs, kRescheduleSamples times in a row, the sound is
// rescheduled (a new source on the anchor, crossfaded over kCrossfadeS).
const kHeldUntilClick = "the browser holds the audio until the page is clicked";
const sound = {
  context: null,
  buffer: null,      // the decoded AudioBuffer
  path: null,        // "webaudio", or "element" (cross-origin audio without CORS: the <audio> element)
  schedule: null,    // {source, gain, startContextS, pieces: [{contextS, positionS, rate}]}
  outOfBand: 0,      // measurements in a row beyond kRescheduleUs
  loadId: 0,
  loading: 0,        // loads under way
  resting: false,    // the context is suspended by the page while idle (startSteering resumes it)
};

/// Resumes the AudioContext that the page suspended while idle.
function wakeAudio() {
  if (!sound.resting) return Promise.resolve();
  sound.resting = false;
  return sound.context.resume().catch(() => {});
}

function audioContext() {
  if (!sound.context) {
    sound.context = new AudioContext({ latencyHint: "interactive" });
    sound.context.onstatechange = () => { viewer.audioContextState = sound.context.state; };
    viewer.audioContextState = sound.context.state;
  }
  return sound.context;
}

/// Whether the server of `url` answers at all: an opaque (no-cors) request resolves for any HTTP
/// status, and fails only when no answer came (connection refused, unknown host, blocked).
async function serverAnswers(url) {
  const controller = new AbortController();
  try {
    await fetch(url, { mode: "no-cors", signal: controller.signal });
    return true;
  } catch (error) {
    return false;
  } finally {
    controller.abort();  // the headers are enough
  }
}

/// Fetches and decodes `source` (a URL, or a File chosen on the page). A URL the browser may not
/// read (another origin without Access-Control-Allow-Origin) falls back to the <audio> element; one
/// whose server does not answer, or answers an error, is named on the status line with what failed.
async function loadAudio(source, name, options = {}) {
  sound.loading += 1;
  try {
    return await fetchAndDecodeAudio(source, name, options);
  } finally {
    sound.loading -= 1;
    startSteering();
  }
}

async function fetchAndDecodeAudio(source, name, { quietNotFound = false }) {
  const id = ++sound.loadId;
  stopSound();
  sound.buffer = null;
  sound.path = null;
  viewer.audio = name;
  viewer.audioError = null;
  viewer.audioLoadedAtMs = null;
  viewer.audioStartOffsetUs = null;
  const context = audioContext();
  await wakeAudio();
  let bytes;
  try {
    if (typeof source === "string") {
      const response = await fetch(source, apiKey && source.startsWith("/") ? { headers: { Authorization: "Bearer " + apiKey } } : {});
      if (!response.ok && response.status === 404 && quietNotFound) {
        if (id === sound.loadId) viewer.audio = null;
        return false;
      }
      if (!response.ok) {
        const text = (await response.text()).trim();
        throw new Error(name + ": HTTP " + response.status + (response.statusText ? " " + response.statusText : "") +
                        (text ? " (" + text + ")" : ""));
      }
      bytes = await response.arrayBuffer();
    } else {
      bytes = await source.arrayBuffer();
    }
  } catch (error) {
    if (id !== sound.loadId) return;
    if (error instanceof TypeError && typeof source === "string") {
      // Not readable from this page (CORS), or no answer at all: the media element may play the first.
      if (!(await serverAnswers(source))) {
        if (id !== sound.loadId) return;
        viewer.audioError = name + ": no answer from its server (connection refused, unknown host, or blocked)";
        setAudioStatus(viewer.audioError);
        return;
      }
      if (id !== sound.loadId) return;
      sound.path = "element";
      viewer.audioPath = "element";
      viewer.audioNote = name + " is not readable from this page (no CORS header?): played by the audio element, " +
                         "which needs a server with byte ranges";
      setAudioStatus(viewer.audioNote);
      elementStartedAtZero = false;
      elementTooLate = false;
      audio.preload = "auto";  // loaded before the anchor, so that an unseekable file starts on time
      audio.src = source;
      return;
    }
    viewer.audioError = error.message;
    setAudioStatus(error.message);
    return;
  }
  let buffer;
  try {
    buffer = await context.decodeAudioData(bytes);
  } catch (error) {
    if (id !== sound.loadId) return;
    viewer.audioError = name + ": not audio the browser can decode (" + error.message + ")";
    setAudioStatus(viewer.audioError);
    return;
  }
  if (id !== sound.loadId) return;
  sound.buffer = buffer;
  sound.path = "webaudio";
  viewer.audioPath = "webaudio";
  viewer.audioDurationUs = Math.round(buffer.duration * 1e6);
  viewer.audioLoadedAtMs = performance.now();
  setAudioStatus(null);
  if (context.state !== "running") {
    context.resume().catch(() => {});
    if (context.state !== "running") {
      viewer.audioError = kHeldUntilClick;
      setAudioStatus("click the page to allow it");
    }
  }
  return true;
}

/// A context time and the performance.now() (ms) at which its sample leaves the speakers.
function outputClock(context) {
  const stamp = context.getOutputTimestamp ? context.getOutputTimestamp() : null;
  if (stamp && stamp.performanceTime > 0) {
    return { contextS: stamp.contextTime, performanceMs: stamp.performanceTime, from: "timestamp" };
  }
  const latencyS = (context.baseLatency || 0) + (context.outputLatency || 0);
  return { contextS: context.currentTime - latencyS, performanceMs: performance.now(), from: "latency" };
}

/// µs of utterance time at performance.now() = `performanceMs`, on the anchor's clock.
function utteranceAtUs(performanceMs) {
  return (performance.timeOrigin + performanceMs) * 1000 - viewer.utteranceZeroUs;
}

/// Seconds into the buffer of the sample played at context time `contextS` (null before the start).
function positionAt(schedule, contextS) {
  if (contextS < schedule.startContextS) return null;
  let piece = schedule.pieces[0];
  for (const p of schedule.pieces) if (p.contextS <= contextS) piece = p;
  return piece.positionS + (contextS - piece.contextS) * piece.rate;
}

function stopSound(atS) {
  const schedule = sound.schedule;
  sound.schedule = null;
  viewer.audioPlaying = false;
  if (!schedule) return;
  const context = sound.context;
  const at = Math.max(atS ?? context.currentTime, context.currentTime);
  schedule.gain.gain.setValueAtTime(1, at);
  schedule.gain.gain.linearRampToValueAtTime(0, at + kCrossfadeS);
  try { schedule.source.stop(at + kCrossfadeS); } catch (e) { /* never started */ }
}

/// Starts the buffer on the anchor: the sample of utterance time t leaves the speakers at t.
function scheduleSound() {
  const context = sound.context;
  const clock = outputClock(context);
  const whenS = context.currentTime + kScheduleAheadS;
  // The utterance time at which the sample rendered at `whenS` is heard.
  const heardUs = utteranceAtUs(clock.performanceMs + (whenS - clock.contextS) * 1000);
  let startS = whenS, offsetS = heardUs / 1e6;
  if (offsetS < 0) { startS -= offsetS; offsetS = 0; }  // utterance time 0 is still to come
  if (offsetS >= sound.buffer.duration) return;
  const previous = sound.schedule;
  if (previous) stopSound(startS);
  const source = context.createBufferSource();
  const gain = context.createGain();
  source.buffer = sound.buffer;
  source.connect(gain).connect(context.destination);
  gain.gain.setValueAtTime(previous ? 0 : 1, startS);
  if (previous) gain.gain.linearRampToValueAtTime(1, startS + kCrossfadeS);
  source.start(startS, offsetS);
  viewer.audioStartOffsetUs ??= Math.round(offsetS * 1e6);
  sound.schedule = { source, gain, startContextS: startS, pieces: [{ contextS: startS, positionS: offsetS, rate: 1 }] };
  sound.outOfBand = 0;
  viewer.locked = false;
  audioInBand = 0;
  viewer.audioClock = clock.from;
}

function steerSound(nowUs) {
  const context = sound.context;
  viewer.audioContextState = context.state;
  if (viewer.held !== null || nowUs === null || context.state !== "running") return;
  if (!sound.schedule) {
    if (nowUs < sound.buffer.duration * 1e6) scheduleSound();
    return;
  }
  const clock = outputClock(context);
  const positionS = positionAt(sound.schedule, clock.contextS);
  if (positionS === null || positionS >= sound.buffer.duration) {
    viewer.audioPlaying = false;
    viewer.drift = null;
    setText(elements.drift, "–");
    return;
  }
  viewer.audioPlaying = true;
  const utteranceUs = utteranceAtUs(clock.performanceMs);
  const drift = Math.round(positionS * 1e6 - utteranceUs);
  viewer.drift = drift;
  setText(elements.drift, (drift / 1000).toFixed(1) + " ms");
  viewer.driftSamples += 1;
  viewer.audioStartedAtUs ??= Math.round(utteranceUs);
  viewer.lastClock = { contextS: clock.contextS, performanceMs: clock.performanceMs, from: clock.from,
                       positionUs: Math.round(positionS * 1e6), utteranceUs: Math.round(utteranceUs),
                       currentTimeS: context.currentTime, baseLatencyS: context.baseLatency ?? null,
                       outputLatencyS: context.outputLatency ?? null };
  noteLock(drift, nowUs);  // every measurement, the ones about to be rescheduled too
  if (Math.abs(drift) > kRescheduleUs) {
    if (++sound.outOfBand >= kRescheduleSamples) {
      viewer.resyncs += 1;
      scheduleSound();
    }
    return;
  }
  sound.outOfBand = 0;
  // Trim: a rate below 1 while the sound is ahead, above 1 while it is behind.
  const rate = 1 - Math.max(-kMaxRateTrim, Math.min(kMaxRateTrim, (drift / 1e6) * kRateGainPerSecond));
  const pieces = sound.schedule.pieces;
  if (Math.abs(rate - pieces[pieces.length - 1].rate) > 1e-4) {
    const at = Math.max(context.currentTime, sound.schedule.startContextS);
    pieces.push({ contextS: at, positionS: positionAt(sound.schedule, at), rate });
    while (pieces.length > 2 && pieces[1].contextS < clock.contextS) pieces.shift();
    sound.schedule.source.playbackRate.setValueAtTime(rate, at);
  }
}

/// Lock bookkeeping, for both paths: kLockSamples measurements in a row within kLockUs.
function noteLock(drift, nowUs) {
  if (viewer.locked) {
    viewer.maxAbsDrift = Math.max(viewer.maxAbsDrift ?? 0, Math.abs(drift));
    viewer.lockedDrifts.push(Math.abs(drift));
    if (viewer.lockedDrifts.length > 1000) viewer.lockedDrifts.shift();
    viewer.lockedSamples += 1;
    return;
  }
  audioInBand = Math.abs(drift) < kLockUs ? audioInBand + 1 : 0;
  if (audioInBand >= kLockSamples) {
    viewer.locked = true;
    viewer.lockedAtUs = nowUs;
  }
}

/// Every kSteerIntervalMs: the drift measured and steered, on whichever path plays the audio.
function steer(nowUs) {
  if (sound.path === "webaudio") steerSound(nowUs);
  else if (sound.path === "element") steerElement(nowUs);
}

// ---------------------------------------------------------------- fallback: the <audio> element

// For a cross-origin URL the page may not read, the media element plays it (it needs a server with
// byte ranges to seek). After a start or a seek: the position it aimed at; drift is measured again
// only once the audio has moved past it (its pipeline runs again) and kSettleAfterStartMs more.
// A file the element cannot seek (a server without byte ranges: `seekable` ends at 0) is never
// seeked (each seek would restart it at 0): it is started from its beginning at the anchor's time
// 0, which only a page opened before the utterance can do, and then trimmed by playback rate alone;
// a page that comes later says on the page why it cannot play the sound in sync.
let audioRestart = null;  // {fromS, runningSinceMs}
let audioInBand = 0;      // consecutive measurements within kLockUs while not locked
let elementOutOfBand = [];  // the element's consecutive drifts beyond its seek threshold (µs)
let audioLeadUs = 0;  // how far ahead of the anchor a seek aims (the pipeline's restart lag)
let audioStarting = false;
let elementStartedAtZero = false;  // an unseekable file was started from its beginning at the anchor
let elementTooLate = false;        // ... or the page came too late for that (said once on the page)

/// Whether the element can seek the file (its server answers byte ranges), once its metadata is known.
function elementCanSeek() {
  const ranges = audio.seekable;
  return ranges.length > 0 && ranges.end(ranges.length - 1) > 0;
}

function explainUnseekable(text) {
  if (viewer.audioNote === text) return;
  viewer.audioNote = text;
  setAudioStatus(text);
}

/// The unseekable element: started from 0 at the anchor's time 0 when the page was there before
/// it, then steered by playback rate only; true when it handled this tick.
function steerUnseekableElement(nowUs) {
  if (!(audio.duration > 0) || elementCanSeek()) return false;
  const name = viewer.audio;
  if (elementTooLate) return true;
  if (!elementStartedAtZero) {
    if (nowUs < 0) return true;  // before the anchor: waits at 0, preloaded
    if (nowUs > kSeekUnlockedUs) {
      elementTooLate = true;
      explainUnseekable(name + " cannot be played in sync: it is not readable from this page (no CORS header) and its " +
                        "server answers no byte ranges, so it can only start from its beginning, and the " +
                        "utterance began " + (nowUs / 1e6).toFixed(2) + " s ago. Open the page before the " +
                        "utterance, serve the file with Access-Control-Allow-Origin, or attach it to the session " +
                        "(lipsync stream --audio FILE.wav)");
      viewer.audioPlaying = false;
      return true;
    }
    elementStartedAtZero = true;
    viewer.locked = false;
    audioInBand = 0;
    audio.playbackRate = 1;
    audioRestart = { fromS: 0, runningSinceMs: null };
    audio.play()
      .catch((e) => { viewer.audioError = e.message; setAudioStatus(e.message + " (click the page to allow it)"); });
    explainUnseekable(name + " is not readable from this page (no CORS header) and its server answers no byte " +
                      "ranges: played by the audio element from its beginning at the anchor, kept in time by its " +
                      "playback rate only (it cannot be seeked)");
    return true;
  }
  if (audio.paused || audio.ended || nowUs / 1e6 >= audio.duration) {
    viewer.audioPlaying = false;
    return true;
  }
  viewer.audioPlaying = true;
  if (audioRestart) {
    if (audio.currentTime <= audioRestart.fromS) return true;
    audioRestart.runningSinceMs ??= performance.now();
    if (performance.now() - audioRestart.runningSinceMs < kSettleAfterStartMs) return true;
    audioRestart = null;
  }
  const drift = Math.round(audio.currentTime * 1e6 - nowUs);
  viewer.drift = drift;
  setText(elements.drift, (drift / 1000).toFixed(1) + " ms");
  viewer.driftSamples += 1;
  audio.playbackRate = 1 - Math.max(-kMaxElementRateTrim, Math.min(kMaxElementRateTrim, (drift / 1e6) * kRateGainPerSecond));
  noteLock(drift, nowUs);
  return true;
}

// Why the element could not play a file (MediaError codes), for the status line.
const kMediaErrors = { 1: "the load was aborted", 2: "a network error", 3: "it could not be decoded",
                       4: "its server answered an error (a missing file?) or it is not audio the browser plays" };

audio.addEventListener("error", () => {
  if (sound.path !== "element" || !audio.error) return;
  const { code, message } = audio.error;
  viewer.audioError = viewer.audio + ": the audio element cannot play it: " + (kMediaErrors[code] || "error " + code) +
                      (message ? " (" + message + ")" : "");
  viewer.audioPlaying = false;
  setAudioStatus(viewer.audioError);
});

function steerElement(nowUs) {
  if (viewer.held !== null || nowUs === null) return;
  if (steerUnseekableElement(nowUs)) return;
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
    elementOutOfBand = [];
    audio.currentTime = (nowUs + audioLeadUs) / 1e6;
    audioRestart = { fromS: audio.currentTime, runningSinceMs: null };
    audio.playbackRate = 1;
    audio.play()
      .catch((e) => { viewer.audioError = e.message; setAudioStatus(e.message + " (click the page to allow it)"); })
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
  setText(elements.drift, (drift / 1000).toFixed(1) + " ms");
  viewer.driftSamples += 1;
  const trim = Math.max(-kMaxElementRateTrim, Math.min(kMaxElementRateTrim, (drift / 1e6) * kRateGainPerSecond));
  audio.playbackRate = 1 - trim;
  if (viewer.locked ? Math.abs(drift) > kResyncUs : Math.abs(drift) > kSeekUnlockedUs) {
    elementOutOfBand.push(drift);
    if (elementOutOfBand.length >= kSeekSamples) {
      seekElement(nowUs, median(elementOutOfBand));
      return;
    }
  } else {
    elementOutOfBand = [];
  }
  noteLock(drift, nowUs);
}

function median(values) {
  const sorted = [...values].sort((a, b) => a - b);
  return sorted[sorted.length >> 1];
}

/// A start or a seek costs the media pipeline a restart, which the audio spends behind the anchor:
/// seek ahead by the lag measured after the last one (the median of the measurements that asked
/// for the seek, so that one jittery reading does not move it), so that it lands on the anchor.
function seekElement(nowUs, drift) {
  elementOutOfBand = [];
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

/// µs of utterance time at which the track ends, once no more frames can come (else null): one
/// frame step after its last frame, or the end of its last phoneme if that is later.
function trackEndUs() {
  if (!(track.summary || track.closed) || !track.frames.length) return null;
  const stepUs = 1e6 / (track.header.fps || 30);
  return Math.max(track.frames[track.frames.length - 1].t + stepUs, track.summary ? track.summary.durationUs : 0);
}

let drawn = { geometry: null, frameIndex: undefined, amount: undefined };
let tickRequested = false;

/// Asks for a tick at the next animation frame (once), and steers the audio again.
function wake() {
  startSteering();
  if (tickRequested) return;
  tickRequested = true;
  viewer.animating = true;
  requestAnimationFrame(tick);
}

/// At an animation frame: the frame for the current utterance time, drawn when it changed. After
/// the track's end the face eases back to rest over kReturnToRestUs. The page asks for the next
/// animation frame only while the picture can change on its own (frames may still come, or the
/// ease is not over); a message, hold() or release() wakes it again.
function tick() {
  tickRequested = false;
  const now = utteranceNowUs();
  if (!track.header || !geometry) {
    viewer.animating = false;
    return;
  }
  const endUs = trackEndUs();
  const toRest = endUs === null || now === null || now < endUs ? 0 : Math.min(1, (now - endUs) / kReturnToRestUs);
  const index = now === null || now < 0 || toRest === 1 ? null : frameAt(now);
  viewer.frameIndex = index;
  const frame = index === null ? null : track.frames[index];
  const amount = 1 - toRest;
  if (drawn.geometry !== geometry || drawn.frameIndex !== index || drawn.amount !== amount) {
    pose(frame, amount);
    draw();
    drawn = { geometry, frameIndex: index, amount };
  }
  showReadouts(frame);
  if (viewer.held === null && toRest < 1) wake();
  else viewer.animating = false;
}

// The audio is steered on a timer of its own: a page that draws slowly (software WebGL on a busy
// machine) still measures and corrects its drift every kSteerIntervalMs. Once the track has ended,
// the face rests and no audio is left to play or load, the timer stops and the AudioContext is
// suspended (even in silence its rendering costs a few per cent of a core); wake() starts both again.
let steerTimer = null;

function startSteering() {
  wakeAudio();
  steerTimer ??= setInterval(steerTick, kSteerIntervalMs);
}

/// Whether audio may still play: loading, or not yet past its end (nothing plays while held).
function audioToCome(nowUs) {
  if (sound.loading) return true;
  if (viewer.held !== null || nowUs === null) return false;
  if (sound.path === "webaudio") return nowUs < sound.buffer.duration * 1e6;
  if (sound.path === "element") return !audio.ended && !(audio.duration > 0 && nowUs >= audio.duration * 1e6);
  return false;
}

function steerTick() {
  if (!track.header) return;
  const now = utteranceNowUs();
  steer(now);
  if (viewer.animating || trackEndUs() === null || audioToCome(now)) return;
  clearInterval(steerTimer);
  steerTimer = null;
  if (sound.context && sound.context.state === "running") {
    sound.resting = true;
    sound.context.suspend().catch(() => {});
  }
}

// ---------------------------------------------------------------- the WebSocket

function onHeader(header) {
  stopWaiting();
  if (viewer.audio && audio.ended) audio.currentTime = 0;  // a new track: the audio may play again
  if (sound.context) stopSound();
  if (sessionAudio === null) askSessionAudio(header.session, "asked");
  setStatus("following " + header.session);
  track.header = header;
  track.frames = [];
  track.eventViseme = null;
  track.summary = null;
  track.closed = false;
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

// Without ?audio= or a chosen file, the page plays the session's own audio from lipsyncd
// (/audio?session=NAME: a Speak session's voice); a session without audio answers 404 and the page
// stays silent.
let sessionAudio = null;  // null, "asked", "absent" (404 once), "retried", "loaded"

function askSessionAudio(session, state) {
  if (params.get("audio") || (viewer.audio && sessionAudio === null)) return;
  sessionAudio = state;
  loadAudio("/audio?session=" + encodeURIComponent(session), "/audio?session=" + session, { quietNotFound: true })
    .then((found) => {
      if (found) sessionAudio = "loaded";
      else if (found === false && sessionAudio === "asked") {
        // Frames that arrived while it was asked for come after a Speak session's audio: once more.
        if (track.frames.length) askSessionAudio(session, "retried"); else sessionAudio = "absent";
      }
    });
}

let waitNote = "";  // why the page waits kWaitForSessionS instead of what ?wait= said

/// Seconds to wait for a session that has not started (?wait=S, 0 to kMaxWaitS; 0: not at all).
function sessionWaitS() {
  const text = params.get("wait");
  if (text === null) return kWaitForSessionS;
  const seconds = /^[0-9]+$/.test(text) ? Number(text) : NaN;
  if (seconds <= kMaxWaitS) return seconds;
  waitNote = "; wait=" + text + " is not whole seconds from 0 to " + kMaxWaitS;
  return kWaitForSessionS;
}

let waitCountdown = null;  // the interval that shows the seconds left while lipsyncd waits for the session

function showWaiting(session, waitS) {
  const until = performance.now() + waitS * 1000;
  const show = () => {
    const left = Math.max(0, Math.ceil((until - performance.now()) / 1000));
    setStatus("waiting for session " + session + " to start (" + left + " s left" + waitNote + ")", !!waitNote);
  };
  viewer.waiting = true;
  viewer.waitingUntilMs = until;
  clearInterval(waitCountdown);
  waitCountdown = setInterval(show, 1000);
  show();
}

function stopWaiting() {
  viewer.waiting = false;
  clearInterval(waitCountdown);
  waitCountdown = null;
}

/// Called with each FrameBatch of the followed session, after its frames are added (live_voice.js).
const frameListeners = [];

function connect(session) {
  const start = params.get("start");
  const waitS = sessionWaitS();
  const url = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws?session=" +
    encodeURIComponent(session) + (start ? "&start=" + encodeURIComponent(start) : "") +
    (waitS ? "&wait_s=" + waitS : "") + (apiKey ? "&key=" + encodeURIComponent(apiKey) : "");
  const socket = new WebSocket(url);
  viewer.socket = socket;  // a later connect() replaces it: the old one's news is ignored
  socket.binaryType = "arraybuffer";
  elements.session.textContent = session;
  if (!viewer.error) setStatus("connecting to " + session);
  socket.onopen = () => { viewer.connected = true; };
  socket.onmessage = (event) => {
    if (socket !== viewer.socket) return;
    if (typeof event.data === "string") {
      // lipsyncd waits for the session ({"waiting", "wait_s"}), or the error before the close ({"code", "message"}).
      const text = JSON.parse(event.data);
      if (text.waiting !== undefined) {
        showWaiting(session, text.wait_s);
        return;
      }
      const waited = viewer.waiting;
      stopWaiting();
      viewer.error = text.code + ": " + text.message;
      setStatus(viewer.error + (waited ? " (Follow waits again)" : ""), true);
      return;
    }
    const message = decodeTrackMessage(new Uint8Array(event.data));
    if (message.header) onHeader(message.header);
    if (message.frames && track.header) {
      addBatch(message.frames);
      for (const listener of frameListeners) listener(message.frames);
      // A Speak session's audio is stored before its first frames: asked for again if the header was too early.
      if (sessionAudio === "absent") askSessionAudio(session, "retried");
    }
    if (message.summary) {
      track.summary = message.summary;
      viewer.ended = true;
      setStatus(session + ": complete, " + message.summary.frames + " frames");
    }
    wake();
  };
  socket.onclose = (event) => {
    if (socket !== viewer.socket) return;
    viewer.connected = false;
    viewer.closeCode = event.code;
    viewer.closeReason = event.reason;
    track.closed = true;
    stopWaiting();
    if (event.code !== 1000 && !viewer.error) {
      viewer.error = "closed (" + event.code + ")" + (event.reason ? ": " + event.reason : "");
      setStatus(viewer.error, true);
    }
    wake();
  };
}

// ---------------------------------------------------------------- the page's forms

function navigate(session, audioUrl) {
  const next = new URLSearchParams();
  if (session) next.set("session", session);
  if (audioUrl) next.set("audio", audioUrl);
  if (params.get("wait") !== null) next.set("wait", params.get("wait"));
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
  loadAudio(file, file.name);
});

/// POST /sessions: the pasted phonemes animated (Animate), or with `speak` the text spoken (Speak,
/// whose session then carries its voice: the page plays it from /audio).
async function quickTry(speak) {
  const query = new URLSearchParams();
  const session = document.getElementById("session-input").value.trim();
  if (session) query.set("session", session);
  if (speak) query.set("speak", "1");
  else if (document.getElementById("try-mesh").checked) query.set("mesh", "1");
  if (apiKey) query.set("key", apiKey);
  elements["try-result"].textContent = speak ? "speaking…" : "animating…";
  const response = await fetch("/sessions?" + query.toString(),
                               { method: "POST", body: document.getElementById("try-text").value });
  const answer = await response.json();
  if (!response.ok) {
    elements["try-result"].textContent = answer.code + ": " + answer.message;
    return;
  }
  navigate(answer.session, !speak && viewer.audio && !viewer.audio.startsWith("blob:") ? params.get("audio") : "");
}

document.getElementById("try-form").addEventListener("submit", (event) => {
  event.preventDefault();
  quickTry(false);
});
document.getElementById("try-speak").addEventListener("click", () => quickTry(true));

if (viewer.audio) loadAudio(viewer.audio, viewer.audio);
document.getElementById("session-input").value = viewer.session || "";
document.getElementById("audio-input").value = viewer.audio || "";
document.addEventListener("click", () => {
  if (sound.context && !sound.resting && sound.context.state !== "running") {
    sound.context.resume().then(() => {
      if (viewer.audioError !== kHeldUntilClick) return;
      viewer.audioError = null;
      setAudioStatus(null);
    });
  }
  if (sound.path === "element" && viewer.audioError) { viewer.audioError = null; audio.play().catch(() => {}); }
});
if (!gl) setStatus("this browser has no WebGL: readouts only", true);

faceAssetLoaded.then(() => {
  if (viewer.session) connect(viewer.session);
  else setStatus("no session: name one, or paste phonemes for a quick try");
});
