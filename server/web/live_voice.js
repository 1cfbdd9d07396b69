// lipsyncd viewer: the page's own voice (docs/viewer.md, "Talk to the face"). Loaded after
// viewer.js, whose functions it uses (connect, setStatus, elements).
//
// **Talk** captures the microphone (getUserMedia); **play a file** plays a sound file that the
// browser decodes as if it were spoken now. Either way an AudioWorklet (/capture_worklet.js) cuts
// the sound into pieces of kPieceMs of 16-bit mono PCM at the AudioContext's rate, and the page
// sends them over a WebSocket of their own (/listen) to lipsyncd, which hears them live (one Listen
// call) into a session named like any other. The page then follows that session on /ws as it
// follows every session, so the face it draws is exactly what any other viewer or Subscribe of the
// session gets.
//
// Time: the session's media-clock anchor (utterance_zero_us, on the "unix" clock) is the moment
// the first sample was heard: the microphone's first piece reached the page less its own length.
// A frame for audio time t is therefore late by the time lipsyncd took, and the page draws the
// newest it has. A file is heard kFileLeadMs after it is captured (a DelayNode before the
// speakers) and its anchor is moved by as much, so its frames arrive before their time and the
// face is drawn in step with the sound the user hears.
//
// Latency (#latency): for each frame that arrives, the time since the end of the piece of sound
// that holds the frame's time reached the page (performance.now() when the worklet's piece came),
// shown as the last value and the 95th percentile of the last kLatencyWindow frames, beside the
// budget asked of lipsyncd.
const kPieceMs = 20;            // a piece of the voice: what a microphone gives at a time
const kFileLeadMs = 500;        // a played file is heard this long after it is captured
const kDefaultBudgetMs = 200;   // the latency budget asked of lipsyncd (?latency=MS: 100 to 2000)
const kLatencyWindow = 150;     // frames in the percentile (5 s at 30 frames/s)
const kMaxQueuedBytes = 512 * 1024;  // unsent voice beyond which the page says lipsyncd is not keeping up
const kMaxLogged = 100000;      // frames kept in live.log (an hour at 30 frames/s)
const kMaxPieces = 500;         // pieces awaiting their frames (10 s): older ones are dropped if frames stop

const live = {
  state: "off",       // "starting", "running", "ending", "ended", "error"
  source: null,       // "microphone" or "file"
  session: null,
  budgetMs: kDefaultBudgetMs,
  sampleRate: null,
  zeroUs: null,       // the session's anchor
  capturedUs: 0,      // audio time at the end of the last piece
  pieces: [],         // [{endUs: audio time at the piece's end, atMs: performance.now() when it came}]
  droppedUs: 0,       // audio time up to which pieces were dropped unanswered (kMaxPieces)
  piecesSent: 0,
  bytesSent: 0,
  latencies: [],      // ms, the last kLatencyWindow frames
  log: [],            // [t µs, latency ms] of every frame measured (at most kMaxLogged), for tests and people
  latencyMs: null,
  latencyP95Ms: null,
  summary: null,      // what lipsyncd said at the end: {session, frames, duration_us, notes}
  error: null,
  socket: null,
  context: null,
  node: null,
  stream: null,       // the microphone's MediaStream
  queued: [],         // pieces captured before the WebSocket opened
};
viewer.live = live;

function liveBudgetMs() {
  const text = params.get("latency");
  const value = text !== null && /^[0-9]+$/.test(text) ? Number(text) : NaN;
  return value >= 100 && value <= 2000 ? value : kDefaultBudgetMs;
}

function showLatency() {
  setText(elements.latency, live.latencyMs === null ? "–"
    : live.latencyMs.toFixed(0) + " ms (p95 " + live.latencyP95Ms.toFixed(0) + ", budget " + live.budgetMs + ")");
}

/// For each batch of the followed session (viewer.js' frameListeners): the latency of each frame in it.
function noteLiveFrames(batch) {
  if (live.state === "off" || !track.header || track.header.session !== live.session) return;
  const now = performance.now();
  for (const t of batch.tUs) {
    const piece = live.pieces.find((p) => p.endUs >= t);
    if (!piece || t <= live.droppedUs) continue;  // its piece is gone: no latency to measure
    live.latencies.push(now - piece.atMs);
    if (live.log.length < kMaxLogged) live.log.push([t, Math.round(now - piece.atMs)]);
  }
  if (live.latencies.length > kLatencyWindow) live.latencies.splice(0, live.latencies.length - kLatencyWindow);
  if (!live.latencies.length) return;
  live.latencyMs = live.latencies[live.latencies.length - 1];
  const sorted = [...live.latencies].sort((a, b) => a - b);
  live.latencyP95Ms = sorted[Math.min(sorted.length - 1, Math.floor(0.95 * sorted.length))];
  // Pieces whose frames have all come are not needed any more.
  const lastT = batch.tUs[batch.tUs.length - 1];
  while (live.pieces.length > 1 && live.pieces[1].endUs < lastT) live.pieces.shift();
  showLatency();
}

function liveFailed(text) {
  live.error = text;
  live.state = "error";
  setStatus(text, true);
  stopCapture();
  updateLiveButtons();
}

function updateLiveButtons() {
  const running = live.state === "starting" || live.state === "running";
  elements.talk.textContent = running && live.source === "microphone" ? "Stop" : "Talk";
  elements.talk.disabled = running && live.source === "file";
  elements["voice-file"].disabled = running;
}

function stopCapture() {
  if (live.stream) live.stream.getTracks().forEach((t) => t.stop());
  if (live.context) live.context.close().catch(() => {});
  live.stream = null;
  live.context = null;
  live.node = null;
}

/// Ends the voice: what was captured is sent, then {"end": true}; lipsyncd answers with the summary.
function endLiveVoice() {
  if (live.state !== "running" && live.state !== "starting") return;
  live.state = "ending";
  const node = live.node;
  if (!node) {
    finishSending();
    return;
  }
  node.port.postMessage("stop");  // the worklet posts the piece it holds, then "stopped"
}

function finishSending() {
  stopCapture();
  if (live.socket && live.socket.readyState === WebSocket.OPEN) live.socket.send(JSON.stringify({ end: true }));
  updateLiveButtons();
}

function onPiece(data) {
  if (data === "stopped") {
    finishSending();
    return;
  }
  const now = performance.now();
  const samples = data.byteLength / 2;
  if (live.zeroUs === null) {
    // The first sample was heard this piece's length before it reached the page.
    const heardUs = Math.round((performance.timeOrigin + now) * 1000 - samples / live.sampleRate * 1e6);
    live.zeroUs = heardUs + (live.source === "file" ? kFileLeadMs * 1000 : 0);
    openListenSocket();
  }
  live.capturedUs += samples / live.sampleRate * 1e6;
  live.pieces.push({ endUs: live.capturedUs, atMs: now });
  if (live.pieces.length > kMaxPieces) live.droppedUs = live.pieces.shift().endUs;  // no frames for 10 s
  if (live.socket && live.socket.readyState === WebSocket.OPEN) sendPiece(data);
  else live.queued.push(data);
}

function sendPiece(data) {
  live.socket.send(data);
  live.piecesSent += 1;
  live.bytesSent += data.byteLength;
  if (live.socket.bufferedAmount > kMaxQueuedBytes && !live.behind) {
    live.behind = true;
    setStatus("lipsyncd is not keeping up: " + (live.socket.bufferedAmount / 2 / live.sampleRate).toFixed(1) +
              " s of the voice wait to be sent", true);
  }
}

function openListenSocket() {
  const query = new URLSearchParams({
    session: live.session, rate: String(live.sampleRate), latency_ms: String(live.budgetMs),
    utterance_zero_us: String(live.zeroUs), visemes: "oculus" });
  const words = elements["talk-words"].value.trim();
  if (words) query.set("transcript", words);
  if (apiKey) query.set("key", apiKey);
  const socket = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/listen?" + query);
  live.socket = socket;
  socket.onopen = () => {
    for (const piece of live.queued) sendPiece(piece);
    live.queued = [];
    if (live.state === "starting") live.state = "running";
    viewer.session = live.session;
    connect(live.session);  // follow the session as any viewer does
  };
  socket.onmessage = (event) => {
    const text = JSON.parse(event.data);
    if (text.code) {
      liveFailed("lipsyncd refused the voice: " + text.code + ": " + text.message);
      return;
    }
    live.summary = text;
  };
  socket.onclose = (event) => {
    if (live.state === "error") return;
    if (event.code === 1000 && live.state === "ending") {
      live.state = "ended";
      updateLiveButtons();
      return;
    }
    liveFailed("the voice's WebSocket closed (" + event.code + (event.reason ? ": " + event.reason : "") + ")");
  };
}

/// Starts the voice from the microphone (`file` null) or from a sound file.
async function startLiveVoice(file) {
  if (live.state === "starting" || live.state === "running") return;
  if (live.socket && live.socket.readyState <= WebSocket.OPEN) live.socket.close();
  if (viewer.socket && viewer.socket.readyState <= WebSocket.OPEN) viewer.socket.close(1000);
  Object.assign(live, { state: "starting", source: file ? "file" : "microphone", error: null, summary: null,
    zeroUs: null, pieces: [], droppedUs: 0, capturedUs: 0, piecesSent: 0, bytesSent: 0, latencies: [], log: [], latencyMs: null,
    latencyP95Ms: null, queued: [], socket: null, behind: false, budgetMs: liveBudgetMs() });
  live.session = document.getElementById("session-input").value.trim() ||
    "mic-" + Array.from(crypto.getRandomValues(new Uint8Array(4)), (b) => b.toString(16).padStart(2, "0")).join("");
  updateLiveButtons();
  showLatency();
  let input;
  try {
    live.context = new AudioContext({ latencyHint: "interactive" });
    if (file) {
      setStatus("decoding " + file.name);
      const buffer = await live.context.decodeAudioData(await file.arrayBuffer());
      input = live.context.createBufferSource();
      input.buffer = buffer;
      const delay = live.context.createDelay(kFileLeadMs / 1000 + 1);
      delay.delayTime.value = kFileLeadMs / 1000;
      input.connect(delay).connect(live.context.destination);
      input.onended = () => endLiveVoice();
    } else {
      if (!navigator.mediaDevices || !navigator.mediaDevices.getUserMedia) {
        throw new Error("this browser gives no microphone to this page (it needs https, or http on localhost)");
      }
      setStatus("asking for the microphone");
      // The voice as spoken: the browser's echo cancelling, noise suppression and gain control
      // change what the recogniser hears (and the page plays nothing while it listens).
      live.stream = await navigator.mediaDevices.getUserMedia({ audio: { channelCount: 1, echoCancellation: false,
        noiseSuppression: false, autoGainControl: false } });
      input = live.context.createMediaStreamSource(live.stream);
    }
    live.sampleRate = live.context.sampleRate;
    await live.context.audioWorklet.addModule("/capture_worklet.js");
    live.node = new AudioWorkletNode(live.context, "lipsync-capture",
      { processorOptions: { pieceFrames: Math.round(live.sampleRate * kPieceMs / 1000) } });
    live.node.port.onmessage = (event) => onPiece(event.data);
    const mute = live.context.createGain();  // the worklet runs only where its output is pulled
    mute.gain.value = 0;
    input.connect(live.node).connect(mute).connect(live.context.destination);
    if (file) input.start();
    await live.context.resume();
    setStatus((file ? "playing " + file.name : "listening") + " into session " + live.session);
  } catch (error) {
    const what = file ? "the file " + file.name + " could not be played" : "the microphone is not available";
    liveFailed(what + ": " + (error.name && error.name !== "Error" ? error.name + ": " : "") + error.message +
               " (the page still follows sessions)");
  }
}

frameListeners.push(noteLiveFrames);
elements.talk = document.getElementById("talk");
elements["voice-file"] = document.getElementById("voice-file");
elements["talk-words"] = document.getElementById("talk-words");
elements.latency = document.getElementById("latency");
elements.talk.addEventListener("click", () => {
  if (live.state === "running" || live.state === "starting") endLiveVoice();
  else startLiveVoice(null);
});
elements["voice-file"].addEventListener("change", (event) => {
  const file = event.target.files[0];
  if (file) startLiveVoice(file);
});
