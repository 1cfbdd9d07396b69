// The viewer's audio on the session's media clock (docs/viewer.md): played so that the sound leaving
// the speakers is at the anchor's time on screen, its drift measured and steered.
//
// An audio file or URL (?audio=URL, a file chosen on the page, or, for a Speak session, lipsyncd's
// own /audio?session=NAME) is fetched whole, decoded, and played on the Web Audio clock: an
// AudioBufferSourceNode started at the context time whose sample leaves the speakers when the
// anchor plays that buffer position (getOutputTimestamp). Every kSteerIntervalMs the sound leaving
// the speakers is compared with the anchor's time on screen (the drift, #drift); a small drift is
// trimmed by the playback rate, a large one rescheduled. No byte ranges are needed. A cross-origin
// URL the page may not read (no CORS header) falls back to the <audio> element, steered by seeks
// (it needs byte ranges).
//
// Loaded before viewer.js (index.html), which loads the audio (loadAudio), wakes the steering
// (startSteering) and stops the sound; this file reads the page's state (viewer, track) and
// readouts only when called.
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
const kSettleAfterStartMs = 60; // after a start or seek, drift is measured once the audio runs again, and this long after

const audio = document.getElementById("audio");

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

// ---------------------------------------------------------------- the steering timer

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
