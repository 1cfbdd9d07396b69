// lipsyncd viewer: the capture side of the page's live voice (docs/viewer.md, "Talk to the face").
// An AudioWorkletProcessor on the audio thread: each render quantum (128 frames) of its input is
// mixed down to mono, converted to 16-bit integers and gathered into pieces of `pieceFrames`
// frames, which are posted to the page as ArrayBuffers (transferred, not copied). A quantum with
// no input (a source not started yet, or ended) counts as silence, so the pieces keep the time of
// the audio clock. "stop" ends it after posting the part of a piece gathered so far.
class CaptureProcessor extends AudioWorkletProcessor {
  constructor(options) {
    super();
    this.pieceFrames = options.processorOptions.pieceFrames;
    this.piece = new Int16Array(this.pieceFrames);
    this.filled = 0;
    this.running = true;
    this.port.onmessage = (event) => {
      if (event.data !== "stop") return;
      if (this.filled) this.port.postMessage(this.piece.slice(0, this.filled).buffer);
      this.filled = 0;
      this.running = false;
      this.port.postMessage("stopped");
    };
  }

  process(inputs) {
    if (!this.running) return false;
    const channels = inputs[0];
    const frames = channels.length ? channels[0].length : 128;
    for (let i = 0; i < frames; ++i) {
      let sum = 0;
      for (const channel of channels) sum += channel[i];
      const value = channels.length ? sum / channels.length : 0;
      this.piece[this.filled++] = Math.max(-32768, Math.min(32767, Math.round(value * 32767)));
      if (this.filled === this.pieceFrames) {
        this.port.postMessage(this.piece.buffer, [this.piece.buffer]);
        this.piece = new Int16Array(this.pieceFrames);
        this.filled = 0;
      }
    }
    return true;
  }
}

registerProcessor("lipsync-capture", CaptureProcessor);
