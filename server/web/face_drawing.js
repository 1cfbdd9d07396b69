// The viewer's face (docs/viewer.md): its geometry posed for a frame and drawn in WebGL. viewer.js
// builds the geometry at each track header (buildGeometry, uploadStatic) and poses and draws it at
// each animation frame that changes the picture (pose, draw).
//
// With the mesh output (the header carries a MeshTopology) the page draws the server's simulated
// vertices. Otherwise it poses the viewer's face (/face.json, data/face/viewer_face.json: the
// physics face fitted as ARKit blendshapes by tools/face/make_viewer_face) with the frame's ARKit
// weights: rest + Σ w_k Δ_k. In both modes the lips are closed at rest (restClosure: the physics
// face's rest, the canonical mesh's, has them 5.5 mm apart). Skin and lips are lit, the skin
// painted from landmark contours (lips, eyes, brows) in a texture laid on the rest pose; the mouth
// cavity, teeth and tongue are drawn in flat colours (kOpenMouthColours) so an open mouth can be
// measured on a screenshot.
//
// Loaded before viewer.js (index.html), whose state (viewer, track) it reads only when called.
"use strict";

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

const canvas = document.getElementById("face");

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

