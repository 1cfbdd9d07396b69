#!/usr/bin/env node
// HeadAudio's visemes for a WAV, in Node, with no browser: the harness's way of asking the
// browser's live audio-to-viseme peer (npm `@met4citizen/headaudio`, MIT) what it shows.
//
// HeadAudio runs in an AudioWorklet: its worklet (modules/headworklet.mjs) hands each 128-sample
// render quantum of mono float audio to `Processor.process` (modules/processor.mjs), which
// resamples to 16 kHz (pre-emphasis, 32-tap polyphase FIR), computes 12 MFCCs over a 512-sample
// (32 ms) window every 256 samples (16 ms), gates silence by energy (VadGate), classifies each
// window by Mahalanobis distance to the model's Gaussian prototypes with a majority vote over
// the last six windows (Classifier), and posts messages through the worklet's port. This script
// does what the worklet and the HeadAudio node (modules/headaudio.mjs) do, in the same order:
//
//   1. `new Processor({sampleRate}, worklet)`, where `worklet.port.postMessage` collects the
//      messages. (The real worklet also passes its AudioParams' defaults; on its first quantum
//      it calls `Processor.update` with them, which leaves every setting as constructed.)
//   2. The model, as `HeadAudio.loadModel` loads it: dist/model-en-mixed.bin cut into records of
//      `PARAMS.RECORD_OFFSET` bytes (368: a header, 12 means, 78 inverse-covariance terms; 39
//      prototypes), each decoded by `new Training().decodeBinaryRecord(Float32Array view)`
//      (an instance method), then `_onmessage({data: {event: "reset"}})` and
//      `_onmessage({data: {event: "model", model}})`.
//   3. The WAV's samples as Float32 (s16 / 32768; stereo is averaged to mono, as the node's
//      `channelInterpretation: "speakers"` down-mix does) in blocks of 128 at the WAV's own rate.
//
// Messages: while speech lasts, one {event: "viseme", viseme, t} per 16 ms window (viseme is an
// index into aa E I O U PP SS TH DD FF kk nn RR CH sil, headaudio.mjs' visemeNames); speech
// starts with {event: "started", t} and stops with {event: "ended", t} when the VAD gate closes
// or the vote gives sil. Printed: the step changes, as JSON on standard output,
//
//   [{"t_us": 1000, "viseme": "PP"}, ..., {"t_us": 1500000, "viseme": "sil"}]
//
// starting with sil at 0, an "ended" message as a step to sil; consecutive equal visemes merge.
//
// What HeadAudio's `t` means (read from processor.mjs, checked with an impulse):
// `t = sampleCount / 16000` counts the 16 kHz samples the resampler has produced, and a viseme
// message's t is `that - 256 / 16000`: the middle of the 512-sample window the MFCCs came from.
// A resampled sample lags the input by the FIR's half length plus one, 16.5 input samples. So on
// the WAV's clock the window's middle is
//
//   t_wav = t + 0.5 / 16000 - 16.5 / sampleRate      (16 kHz WAV: exactly t - 1 ms)
//
// which is what t_us holds (to within 0.2 ms at 22.05-48 kHz, where the resampler's phase
// rounding moves it). An "ended" message's t is the window's end, not its middle (no "- 256 /
// 16000"); it is moved to the middle like the others, so every event sits at the middle of the
// window that decided it. The message itself is posted half a window (16 ms) after its t, and
// the viseme it carries is the most frequent nearest prototype of the last six windows (96 ms;
// a tie goes to the higher index, so sil wins ties), so a change shows some windows late.
//
// --node-reading applies the HeadAudio node's own reading of the messages (headaudio.mjs
// `_onmessage`): it takes a viseme message only `if (viseme)`, so index 0, aa, never becomes the
// active viseme: the mouth keeps the viseme before it. That is what an avatar driven by the node
// shows; without the option the processor's messages are printed as they are.
//
//   node tools/headaudio/run_headaudio.mjs WAV [--package DIR] [--node-reading]
//
// DIR is the unpacked package (default build/headaudio/package, which
// tools/headaudio/fetch_headaudio.sh makes). A WAV that is not 16-bit PCM, mono or stereo, or
// that cannot be read, exits with status 1 and a message naming the file; a bad command line
// with status 2. Needs Node 18 or newer (Debian 12's is 18).
import fs from "node:fs";
import path from "node:path";
import { fileURLToPath, pathToFileURL } from "node:url";

const kUsage = "usage: run_headaudio.mjs WAV [--package DIR] [--node-reading]";
const kRepoRoot = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "..", "..");
const kDefaultPackage = path.join(kRepoRoot, "build", "headaudio", "package");
const kQuantumSamples = 128; // an AudioWorklet's render quantum
// headaudio.mjs' visemeNames without their "viseme_" prefix: Oculus names, by HeadAudio's index.
const kVisemeNames = ["aa", "E", "I", "O", "U", "PP", "SS", "TH", "DD", "FF", "kk", "nn", "RR", "CH", "sil"];

class UsageError extends Error {}
class InputError extends Error {}

function parseArguments(argv) {
  const options = { wav: null, packageDir: kDefaultPackage, nodeReading: false };
  for (let i = 0; i < argv.length; i++) {
    const arg = argv[i];
    if (arg === "--help" || arg === "-h") {
      console.log(kUsage);
      process.exit(0);
    } else if (arg === "--package") {
      if (i + 1 >= argv.length) throw new UsageError("--package needs a DIR");
      options.packageDir = path.resolve(argv[++i]);
    } else if (arg === "--node-reading") {
      options.nodeReading = true;
    } else if (arg.startsWith("-")) {
      throw new UsageError(`unknown option ${arg}`);
    } else if (options.wav === null) {
      options.wav = arg;
    } else {
      throw new UsageError(`one WAV only (also got ${arg})`);
    }
  }
  if (options.wav === null) throw new UsageError("a WAV is needed");
  return options;
}

/// A RIFF WAVE file of 16-bit PCM, mono or stereo: its rate and its samples as mono floats.
function readPcmWav(file) {
  let bytes;
  try {
    bytes = fs.readFileSync(file);
  } catch (error) {
    throw new InputError(`${file}: cannot read it (${error.code ?? error.message})`);
  }
  const fail = (why) => {
    throw new InputError(`${file}: ${why}`);
  };
  if (bytes.length < 12 || bytes.toString("latin1", 0, 4) !== "RIFF" || bytes.toString("latin1", 8, 12) !== "WAVE") {
    fail("not a WAV file (no RIFF/WAVE header)");
  }
  let format = null;
  let data = null;
  for (let pos = 12; pos + 8 <= bytes.length; ) {
    const id = bytes.toString("latin1", pos, pos + 4);
    const size = bytes.readUInt32LE(pos + 4);
    const body = bytes.subarray(pos + 8, Math.min(bytes.length, pos + 8 + size));
    if (id === "fmt ") {
      if (body.length < 16) fail("its fmt chunk is shorter than 16 bytes");
      let tag = body.readUInt16LE(0);
      if (tag === 0xfffe && body.length >= 26) tag = body.readUInt16LE(24); // WAVE_FORMAT_EXTENSIBLE's subformat
      format = { tag, channels: body.readUInt16LE(2), rateHz: body.readUInt32LE(4), bits: body.readUInt16LE(14) };
    } else if (id === "data") {
      data = body; // a data chunk cut short (a stream's header) is read up to the file's end
    }
    pos += 8 + size + (size % 2); // chunks are padded to an even length
  }
  if (format === null) fail("no fmt chunk");
  if (data === null) fail("no data chunk");
  if (format.tag !== 1) fail(`not PCM (format tag ${format.tag}); 16-bit PCM is needed`);
  if (format.bits !== 16) fail(`${format.bits}-bit samples; 16-bit PCM is needed`);
  if (format.channels !== 1 && format.channels !== 2) fail(`${format.channels} channels; mono or stereo is needed`);
  if (format.rateHz < 8000 || format.rateHz > 192000) fail(`sample rate ${format.rateHz} Hz is outside 8000-192000`);
  const frames = Math.floor(data.length / (2 * format.channels));
  if (frames === 0) fail("no samples");
  const samples = new Float32Array(frames);
  for (let i = 0; i < frames; i++) {
    let sum = 0;
    for (let c = 0; c < format.channels; c++) sum += data.readInt16LE(2 * (i * format.channels + c));
    samples[i] = sum / format.channels / 32768;
  }
  return { rateHz: format.rateHz, samples };
}

/// The package's modules, or an error that says to fetch it.
async function importHeadAudio(packageDir) {
  const module = (name) => path.join(packageDir, "modules", name);
  for (const file of [module("processor.mjs"), module("training.mjs"), path.join(packageDir, "dist", "model-en-mixed.bin")]) {
    if (!fs.existsSync(file)) {
      throw new InputError(`${file} is missing: fetch HeadAudio first (tools/headaudio/fetch_headaudio.sh), or name its unpacked folder with --package`);
    }
  }
  const [{ Processor }, { Training }, PARAMS] = await Promise.all([
    import(pathToFileURL(module("processor.mjs"))),
    import(pathToFileURL(module("training.mjs"))),
    import(pathToFileURL(module("parameters.mjs"))),
  ]);
  if (PARAMS.MODEL_VISEMES_N !== kVisemeNames.length || kVisemeNames[PARAMS.MODEL_VISEME_SIL] !== "sil") {
    throw new InputError(`${packageDir}: a HeadAudio with ${PARAMS.MODEL_VISEMES_N} visemes (sil at ${PARAMS.MODEL_VISEME_SIL}); this script knows 15 with sil at 14`);
  }
  return { Processor, Training, PARAMS };
}

/// The prototypes of dist/model-en-mixed.bin, as Training.loadModel decodes them (it fetch()es
/// the file, which Node cannot do for a path; the loop is the same).
function decodeModel(packageDir, Training, PARAMS) {
  const file = path.join(packageDir, "dist", "model-en-mixed.bin");
  const buffer = new Uint8Array(fs.readFileSync(file)).buffer; // a copy: its own, aligned ArrayBuffer
  const training = new Training();
  const model = [];
  for (let pos = 0; pos + PARAMS.RECORD_OFFSET <= buffer.byteLength; pos += PARAMS.RECORD_OFFSET) {
    model.push(training.decodeBinaryRecord(new Float32Array(buffer, pos, PARAMS.RECORD_LEN)));
  }
  if (model.length === 0) throw new InputError(`${file}: no prototypes in it`);
  return model;
}

/// Every message the processor posts for `samples`, fed in render quanta.
function runProcessor({ Processor }, model, rateHz, samples) {
  const messages = [];
  const worklet = { port: { onmessage: null, postMessage: (message) => messages.push(message) } };
  const processor = new Processor({ sampleRate: rateHz }, worklet);
  processor._onmessage({ data: { event: "reset" } });
  processor._onmessage({ data: { event: "model", model } });
  for (let start = 0; start < samples.length; start += kQuantumSamples) {
    processor.process(samples.subarray(start, start + kQuantumSamples));
  }
  return messages;
}

/// The step changes of the shown viseme, in µs on the WAV's clock (see the header for the clock).
function visemeSteps(messages, { PARAMS }, rateHz, nodeReading) {
  const halfWindowS = PARAMS.MFCC_SAMPLES_N / 2 / PARAMS.AUDIO_SAMPLE_RATE;
  const resamplerLagS = ((PARAMS.AUDIO_DOWNSAMPLE_FILTER_N - 1) / 2 + 1) / rateHz;
  const windowMiddleUs = (t) => Math.round((t + 0.5 / PARAMS.AUDIO_SAMPLE_RATE - resamplerLagS) * 1e6);
  const steps = [{ t_us: 0, viseme: "sil" }];
  const step = (tUs, viseme) => {
    const at = Math.max(0, tUs);
    while (steps.length > 0 && at <= steps[steps.length - 1].t_us) steps.pop(); // a later message at the same time wins
    if (steps.length === 0 || steps[steps.length - 1].viseme !== viseme) steps.push({ t_us: at, viseme });
  };
  for (const message of messages) {
    if (message.event === "viseme") {
      if (message.viseme === null || message.viseme === undefined) continue;
      if (nodeReading && !message.viseme) continue; // headaudio.mjs: `if ( viseme ) { ... }`
      step(windowMiddleUs(message.t), kVisemeNames[message.viseme]);
    } else if (message.event === "ended") {
      step(windowMiddleUs(message.t - halfWindowS), "sil");
    }
  }
  return steps;
}

async function main() {
  let options;
  try {
    options = parseArguments(process.argv.slice(2));
  } catch (error) {
    if (!(error instanceof UsageError)) throw error;
    console.error(`run_headaudio: ${error.message}\n${kUsage}`);
    process.exit(2);
  }
  try {
    const { rateHz, samples } = readPcmWav(options.wav);
    const headaudio = await importHeadAudio(options.packageDir);
    const model = decodeModel(options.packageDir, headaudio.Training, headaudio.PARAMS);
    const messages = runProcessor(headaudio, model, rateHz, samples);
    const steps = visemeSteps(messages, headaudio, rateHz, options.nodeReading);
    process.stdout.write("[" + steps.map((s) => JSON.stringify(s)).join(",\n") + "]\n");
  } catch (error) {
    if (!(error instanceof InputError)) throw error;
    console.error(`run_headaudio: ${error.message}`);
    process.exit(1);
  }
}

await main();
