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
// - Audio (audio_steering.js). The session's audio, ?audio=URL or a file chosen on the page plays
//   on the anchor: its drift from the anchor's time on screen (#drift) is measured and steered.
//   The face follows the anchor, not the audio, so that a stalled or missing audio never freezes
//   the face.
// - The face (face_drawing.js). The frame's pose (the server's simulated mesh, or the viewer's
//   face with the frame's ARKit weights), drawn in WebGL.
//
// The page's scripts are classic scripts sharing one global scope, loaded in order by index.html:
// face_drawing.js and audio_steering.js (what they declare, called from here), then this one (the
// page's state, the track as received, the readouts, the animation loop, the WebSocket and the
// forms; it starts the page), then live_voice.js.
//
// Its state is on window.lipsyncViewer and in the elements #frame-time (µs), #viseme and #drift.
"use strict";

const kReturnToRestUs = 250000; // after the track's end the face eases back to rest over this
const kWaitForSessionS = 120;   // lipsyncd waits this long for a session that has not started (?wait=S)
const kMaxWaitS = 3600;

const params = new URLSearchParams(location.search);
// A server with --api-keys: the key travels to lipsyncd as ?key= (docs/viewer.md).
const apiKey = params.get("key");
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
