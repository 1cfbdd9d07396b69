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
// frequency), exact enough for a speech recogniser's 16 kHz input; StreamingResampler gives the
// same samples from audio that arrives in pieces (a live stream).
#pragma once

#include <cstdint>
#include <ostream>
#include <span>
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

/// Audio that arrives in pieces (a live stream): raw 16-bit little-endian PCM of a given rate and
/// channel count, or a WAV file whose header comes first (any encoding decode_wav reads; a data
/// size of 0 or 0xFFFFFFFF, as a streaming writer leaves it, is read to the end of the stream). The
/// pieces may split a sample frame or the header anywhere. Channels are averaged to mono as
/// decode_wav averages them.
class AudioStreamReader {
 public:
  enum class Encoding { pcm_s16le, wav };
  /// The longest WAV header read before its sample data must have begun.
  static constexpr std::size_t kMaxWavHeaderBytes = 64 * 1024;

  /// `sample_rate_hz` and `channels`: raw PCM's (required); for a WAV 0, or what its header must
  /// say. `source` names the stream in errors.
  AudioStreamReader(Encoding encoding, int sample_rate_hz, int channels, std::string source);

  /// Appends the mono samples that `bytes` complete to `out`. Throws InputError: not a WAV file,
  /// an encoding it does not read, a header longer than kMaxWavHeaderBytes, a rate or channel count
  /// other than the one asked for.
  void push(std::string_view bytes, std::vector<std::int16_t>& out);
  /// The stream has ended. Throws InputError if it stopped inside a WAV header or a sample frame.
  void finish() const;

  /// The samples' rate: 0 until a WAV's header has been read.
  int sample_rate_hz() const { return layout_.sample_rate_hz; }
  /// The layout of the bytes (raw PCM: 16-bit integer), once known.
  const WavLayout& layout() const { return layout_; }
  /// Bytes of sample data read so far.
  std::uint64_t data_bytes() const { return data_bytes_; }

 private:
  void read_samples(std::string_view bytes, std::vector<std::int16_t>& out);

  Encoding encoding_;
  std::string source_;
  int wanted_rate_hz_;
  int wanted_channels_;
  WavLayout layout_;
  bool header_read_ = false;
  std::string header_;                    // a WAV's first bytes, until its data begins
  std::uint64_t data_left_ = UINT64_MAX;  // a WAV's declared data size still to come
  std::string partial_frame_;             // bytes of a sample frame split between pieces
  std::uint64_t data_bytes_ = 0;
};

/// `audio` at `rate_hz` (a copy when the rate already matches).
PcmAudio resample(const PcmAudio& audio, int rate_hz);

/// resample() for audio that arrives in pieces: each output sample leaves as soon as every input
/// sample its kernel reads has come, and the samples of all pieces and finish() together are
/// exactly resample() of the whole input. Holds only the input that later output samples read.
class StreamingResampler {
 public:
  StreamingResampler(int from_hz, int to_hz);
  /// Appends the output samples that `samples` completes to `out`.
  void push(std::span<const std::int16_t> samples, std::vector<std::int16_t>& out);
  /// The input has ended: appends the rest.
  void finish(std::vector<std::int16_t>& out);

 private:
  void emit(bool finishing, std::vector<std::int16_t>& out);

  int from_hz_;
  int to_hz_;
  std::vector<std::int16_t> held_;  // input samples [held_from_, received_)
  std::int64_t held_from_ = 0;
  std::int64_t received_ = 0;
  std::int64_t next_ = 0;  // the next output sample
};

/// Writes a canonical 44-byte-header PCM WAV (mono, 16-bit).
void write_wav(std::ostream& out, const PcmAudio& audio);

/// `samples` as raw signed 16-bit little-endian bytes (the Listen RPC's PCM_S16LE).
std::string pcm_s16le_bytes(std::span<const std::int16_t> samples);

/// Appends a silent interval to `utterance` so that a track rendered from it on the
/// uniform grid at `fps` has a frame at or after `audio_end_us`: the track then
/// covers the whole audio and a player never holds a stale pose at its end. Does
/// nothing when the phonemes already reach one grid step past the audio.
void cover_audio(LabeledUtterance& utterance, std::int64_t audio_end_us, int fps);

}  // namespace lipsync::speech
