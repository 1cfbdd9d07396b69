// Audio for the speech front-ends: 16-bit PCM in memory, the WAV files it comes
// from and goes to, and the conversions the aligner needs.
//
// The reader accepts what recorders and synthesisers commonly write: RIFF/WAVE
// with PCM 8/16/24/32-bit integer or 32/64-bit float samples, any channel count,
// the WAVE_FORMAT_EXTENSIBLE header, odd-sized chunks and a data size left at
// 0xFFFFFFFF by a streaming writer. Channels are averaged to mono and samples
// rounded to 16 bits; every such conversion is reported back as a note (a
// sentence for the user) rather than logged, so the caller decides where it goes.
// Anything else (not RIFF, a compressed codec, no data chunk) is an InputError
// naming the file and what was found.
//
// resample() is a windowed-sinc resampler (Blackman window, 16 zero crossings of
// the low-pass kernel on each side, cut-off at 0.95 of the lower Nyquist
// frequency), exact enough for a speech recogniser's 16 kHz input.
#pragma once

#include <cstdint>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/utterance.hpp"

namespace lipsync::speech {

/// Mono 16-bit PCM.
struct PcmAudio {
  int sample_rate_hz = 16000;
  std::vector<std::int16_t> samples;

  /// Length in microseconds (samples / rate, rounded down).
  std::int64_t duration_us() const;
};

/// What a WAV file held before conversion to mono 16-bit.
struct WavLayout {
  int sample_rate_hz = 0;
  int channels = 0;
  int bits_per_sample = 0;
  bool floating_point = false;
};

struct DecodedWav {
  PcmAudio audio;                  ///< mono, 16-bit, at the file's own rate
  WavLayout layout;                ///< as found in the file
  std::vector<std::string> notes;  ///< conversions done ("2 channels averaged to mono", ...)
};

/// True if `bytes` start like a RIFF/WAVE file (for input-format detection).
bool looks_like_wav(std::string_view bytes);

/// Decodes a WAV file's bytes; `source` names it in errors. Throws InputError.
DecodedWav decode_wav(std::string_view bytes, std::string_view source);

/// Reads only the header of a WAV file's bytes: its layout and length in µs. Throws InputError.
std::pair<WavLayout, std::int64_t> wav_layout_and_duration_us(std::string_view bytes, std::string_view source);

/// `audio` at `rate_hz` (a copy when the rate already matches).
PcmAudio resample(const PcmAudio& audio, int rate_hz);

/// Writes a canonical 44-byte-header PCM WAV (mono, 16-bit).
void write_wav(std::ostream& out, const PcmAudio& audio);

/// Appends a silent interval to `utterance` so that a track rendered from it on the
/// uniform grid at `fps` has a frame at or after `audio_end_us`: the track then
/// covers the whole audio and a player never holds a stale pose at its end. Does
/// nothing when the phonemes already reach one grid step past the audio.
void cover_audio(LabeledUtterance& utterance, std::int64_t audio_end_us, int fps);

}  // namespace lipsync::speech
