// WAV decoding and encoding, resampling and the trailing silence that makes a
// track cover its audio (lipsync/speech/audio.hpp).
#include "lipsync/speech/audio.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

#include "lipsync/error.hpp"

namespace lipsync::speech {
namespace {

constexpr std::uint16_t kFormatPcm = 1;
constexpr std::uint16_t kFormatFloat = 3;
constexpr std::uint16_t kFormatExtensible = 0xFFFE;

std::uint32_t read_u32(std::string_view bytes, std::size_t at) {
  std::uint32_t value = 0;
  for (std::size_t i = 0; i < 4; ++i) value |= std::uint32_t(static_cast<std::uint8_t>(bytes[at + i])) << (8 * i);
  return value;
}

std::uint16_t read_u16(std::string_view bytes, std::size_t at) {
  return static_cast<std::uint16_t>(static_cast<std::uint8_t>(bytes[at]) |
                                    (static_cast<std::uint8_t>(bytes[at + 1]) << 8));
}

// The fmt chunk's fields and where the sample data lies in the file.
struct WavChunks {
  WavLayout layout;
  std::size_t data_offset = 0;
  std::size_t data_size = 0;  // clamped to the bytes present, whole frames only
};

WavChunks find_chunks(std::string_view bytes, std::string_view source) {
  const std::string where(source);
  if (!looks_like_wav(bytes)) {
    std::string found =
        bytes.size() < 12 ? std::to_string(bytes.size()) + " bytes" : "'" + std::string(bytes.substr(0, 4)) + "'";
    throw InputError(where, 0, "not a WAV file (expected a RIFF/WAVE header, found " + found + ")");
  }
  WavChunks chunks;
  bool have_format = false;
  std::uint16_t format_tag = 0;
  std::size_t at = 12;
  while (at + 8 <= bytes.size()) {
    const std::string_view id = bytes.substr(at, 4);
    const std::size_t size = read_u32(bytes, at + 4);
    const std::size_t body = at + 8;
    if (id == "fmt ") {
      if (size < 16 || body + size > bytes.size()) throw InputError(where, 0, "WAV 'fmt ' chunk is truncated");
      format_tag = read_u16(bytes, body);
      chunks.layout.channels = read_u16(bytes, body + 2);
      chunks.layout.sample_rate_hz = static_cast<int>(read_u32(bytes, body + 4));
      chunks.layout.bits_per_sample = read_u16(bytes, body + 14);
      if (format_tag == kFormatExtensible && size >= 26) format_tag = read_u16(bytes, body + 24);
      have_format = true;
    } else if (id == "data") {
      if (!have_format) throw InputError(where, 0, "WAV 'data' chunk comes before the 'fmt ' chunk");
      chunks.data_offset = body;
      chunks.data_size = std::min(size, bytes.size() - body);  // a streaming writer may leave 0xFFFFFFFF
      break;
    }
    at = body + size + (size & 1);
  }
  if (!have_format) throw InputError(where, 0, "WAV file has no 'fmt ' chunk");
  if (chunks.data_offset == 0) throw InputError(where, 0, "WAV file has no 'data' chunk");
  WavLayout& layout = chunks.layout;
  layout.floating_point = format_tag == kFormatFloat;
  const bool integer_ok = format_tag == kFormatPcm && (layout.bits_per_sample == 8 || layout.bits_per_sample == 16 ||
                                                       layout.bits_per_sample == 24 || layout.bits_per_sample == 32);
  const bool float_ok = layout.floating_point && (layout.bits_per_sample == 32 || layout.bits_per_sample == 64);
  if (!integer_ok && !float_ok) {
    throw InputError(where, 0,
                     "unsupported WAV encoding (format tag " + std::to_string(format_tag) + ", " +
                         std::to_string(layout.bits_per_sample) +
                         " bits): only PCM 8/16/24/32-bit integer and 32/64-bit float are read");
  }
  if (layout.channels < 1) throw InputError(where, 0, "WAV file declares 0 channels");
  if (layout.sample_rate_hz < 1) throw InputError(where, 0, "WAV file declares a sample rate of 0 Hz");
  const std::size_t frame_bytes = std::size_t(layout.channels) * std::size_t(layout.bits_per_sample / 8);
  chunks.data_size -= chunks.data_size % frame_bytes;
  return chunks;
}

// One sample as a value in [-1, 1).
double sample_value(const char* p, const WavLayout& layout) {
  const auto byte = [&](int i) { return static_cast<std::uint8_t>(p[i]); };
  switch (layout.bits_per_sample) {
    case 8:
      return (byte(0) - 128) / 128.0;
    case 16:
      return static_cast<std::int16_t>(byte(0) | (byte(1) << 8)) / 32768.0;
    case 24: {
      const std::int32_t v = (byte(0) << 8) | (byte(1) << 16) | (byte(2) << 24);  // sign from the top byte
      return (v >> 8) / 8388608.0;
    }
    case 32:
      if (layout.floating_point) {
        float f = 0;
        std::memcpy(&f, p, 4);
        return f;
      }
      return static_cast<std::int32_t>(byte(0) | (byte(1) << 8) | (byte(2) << 16) | (std::uint32_t(byte(3)) << 24)) /
             2147483648.0;
    default: {  // 64-bit float
      double d = 0;
      std::memcpy(&d, p, 8);
      return d;
    }
  }
}

std::int16_t to_int16(double value) {
  if (!std::isfinite(value)) return 0;
  return static_cast<std::int16_t>(std::clamp(std::lround(value * 32768.0), -32768L, 32767L));
}

}  // namespace

std::int64_t PcmAudio::duration_us() const {
  return static_cast<std::int64_t>(samples.size()) * 1'000'000 / sample_rate_hz;
}

bool looks_like_wav(std::string_view bytes) {
  return bytes.size() >= 12 && bytes.substr(0, 4) == "RIFF" && bytes.substr(8, 4) == "WAVE";
}

std::pair<WavLayout, std::int64_t> wav_layout_and_duration_us(std::string_view bytes, std::string_view source) {
  const WavChunks chunks = find_chunks(bytes, source);
  const auto frames = static_cast<std::int64_t>(
      chunks.data_size / (std::size_t(chunks.layout.channels) * (chunks.layout.bits_per_sample / 8)));
  return {chunks.layout, frames * 1'000'000 / chunks.layout.sample_rate_hz};
}

DecodedWav decode_wav(std::string_view bytes, std::string_view source) {
  const WavChunks chunks = find_chunks(bytes, source);
  DecodedWav decoded;
  decoded.layout = chunks.layout;
  const WavLayout& layout = chunks.layout;
  const std::size_t sample_bytes = std::size_t(layout.bits_per_sample / 8);
  const std::size_t frame_bytes = sample_bytes * std::size_t(layout.channels);
  const std::size_t frames = chunks.data_size / frame_bytes;
  decoded.audio.sample_rate_hz = layout.sample_rate_hz;
  decoded.audio.samples.resize(frames);
  const char* data = bytes.data() + chunks.data_offset;
  for (std::size_t i = 0; i < frames; ++i) {
    double sum = 0;
    for (int c = 0; c < layout.channels; ++c)
      sum += sample_value(data + i * frame_bytes + std::size_t(c) * sample_bytes, layout);
    decoded.audio.samples[i] = to_int16(sum / layout.channels);
  }
  if (layout.channels > 1) decoded.notes.push_back(std::to_string(layout.channels) + " channels averaged to mono");
  if (layout.bits_per_sample != 16 || layout.floating_point) {
    decoded.notes.push_back(std::to_string(layout.bits_per_sample) + "-bit " +
                            (layout.floating_point ? "float" : "integer") + " samples converted to 16-bit");
  }
  return decoded;
}

AudioStreamReader::AudioStreamReader(Encoding encoding, int sample_rate_hz, int channels, std::string source)
    : encoding_(encoding), source_(std::move(source)), wanted_rate_hz_(sample_rate_hz), wanted_channels_(channels) {
  if (encoding_ == Encoding::pcm_s16le) {
    layout_ = {sample_rate_hz, channels, 16, false};
    header_read_ = true;
  }
}

void AudioStreamReader::push(std::string_view bytes, std::vector<std::int16_t>& out) {
  if (header_read_) {
    read_samples(bytes, out);
    return;
  }
  header_ += bytes;
  // Is the header complete, i.e. has the 'data' chunk's own header come?
  bool data_started = false;
  if (header_.size() >= 12 && looks_like_wav(header_)) {
    for (std::size_t at = 12; at + 8 <= header_.size();) {
      if (std::string_view(header_).substr(at, 4) == "data") {
        data_started = true;
        break;
      }
      const std::size_t size = read_u32(header_, at + 4);
      at += 8 + size + (size & 1);
    }
  } else if (header_.size() >= 12) {
    find_chunks(header_, source_);  // throws: not a WAV file
  }
  if (!data_started) {
    if (header_.size() > kMaxWavHeaderBytes) {
      throw InputError(source_, 0,
                       "the WAV header is longer than " + std::to_string(kMaxWavHeaderBytes) +
                           " bytes without its 'data' chunk (a live WAV stream must start with its header)");
    }
    return;
  }
  const WavChunks chunks = find_chunks(header_, source_);
  layout_ = chunks.layout;
  if (wanted_rate_hz_ != 0 && layout_.sample_rate_hz != wanted_rate_hz_) {
    throw InputError(source_, 0,
                     "the WAV header says " + std::to_string(layout_.sample_rate_hz) + " Hz, but the stream's " +
                         "sample_rate_hz is " + std::to_string(wanted_rate_hz_));
  }
  if (wanted_channels_ != 0 && layout_.channels != wanted_channels_) {
    throw InputError(source_, 0,
                     "the WAV header says " + std::to_string(layout_.channels) + " channels, but the stream's " +
                         "channels is " + std::to_string(wanted_channels_));
  }
  const std::uint32_t declared = read_u32(header_, chunks.data_offset - 4);
  if (declared != 0 && declared != 0xFFFFFFFFU) data_left_ = declared;
  header_read_ = true;
  const std::string rest = header_.substr(chunks.data_offset);
  header_ = std::string();
  read_samples(rest, out);
}

void AudioStreamReader::read_samples(std::string_view bytes, std::vector<std::int16_t>& out) {
  if (data_left_ != UINT64_MAX) {  // bytes after a WAV's declared data are other chunks
    bytes = bytes.substr(0, static_cast<std::size_t>(std::min<std::uint64_t>(bytes.size(), data_left_)));
    data_left_ -= bytes.size();
  }
  data_bytes_ += bytes.size();
  const std::size_t sample_bytes = std::size_t(layout_.bits_per_sample / 8);
  const std::size_t frame_bytes = sample_bytes * std::size_t(layout_.channels);
  const auto frame = [&](const char* data) {
    double sum = 0;
    for (int c = 0; c < layout_.channels; ++c) sum += sample_value(data + std::size_t(c) * sample_bytes, layout_);
    out.push_back(to_int16(sum / layout_.channels));
  };
  if (!partial_frame_.empty()) {
    const std::size_t missing = std::min(frame_bytes - partial_frame_.size(), bytes.size());
    partial_frame_.append(bytes.substr(0, missing));
    bytes.remove_prefix(missing);
    if (partial_frame_.size() < frame_bytes) return;
    frame(partial_frame_.data());
    partial_frame_.clear();
  }
  const std::size_t whole = bytes.size() / frame_bytes;
  for (std::size_t i = 0; i < whole; ++i) frame(bytes.data() + i * frame_bytes);
  partial_frame_.assign(bytes.substr(whole * frame_bytes));
}

void AudioStreamReader::finish() const {
  if (!header_read_) {
    throw InputError(
        source_, 0,
        "the stream ended inside the WAV header (" + std::to_string(header_.size()) + " bytes, no 'data' chunk)");
  }
  if (!partial_frame_.empty()) {
    throw InputError(source_, 0,
                     "the stream ended inside a sample frame (" + std::to_string(partial_frame_.size()) +
                         " bytes left over; a frame is " +
                         std::to_string(layout_.channels * (layout_.bits_per_sample / 8)) + " bytes)");
  }
}

namespace {

// The windowed-sinc low-pass kernel both resamplers use: Blackman window, 16 zero crossings of
// the sinc on each side, cut-off at 0.95 of the lower Nyquist frequency.
struct SincKernel {
  explicit SincKernel(int from_hz, int to_hz)
      : ratio(double(to_hz) / from_hz), cutoff(0.95 * std::min(1.0, ratio)), half_width(16.0 / cutoff) {}

  /// The first and last input sample the output sample `n` reads (unclamped).
  std::int64_t first_input(std::int64_t n) const {
    return static_cast<std::int64_t>(std::ceil(double(n) / ratio - half_width));
  }
  std::int64_t last_input(std::int64_t n) const {
    return static_cast<std::int64_t>(std::floor(double(n) / ratio + half_width));
  }

  /// Output sample `n` from the input samples [first, last] (clamped to what exists), where
  /// `at(k)` is input sample k.
  template <class At>
  std::int16_t output(std::int64_t n, std::int64_t first, std::int64_t last, At at) const {
    const double centre = double(n) / ratio;  // the output sample's time, in input samples
    double sum = 0;
    for (std::int64_t k = first; k <= last; ++k) {
      const double x = double(k) - centre;
      const double arg = std::numbers::pi * cutoff * x;
      const double sinc = x == 0 ? 1.0 : std::sin(arg) / arg;
      const double phase = std::numbers::pi * (x / half_width + 1.0);  // Blackman window over [-w, w]
      const double window = 0.42 - 0.5 * std::cos(phase) + 0.08 * std::cos(2 * phase);
      sum += at(k) * cutoff * sinc * window;
    }
    return to_int16(sum / 32768.0);
  }

  double ratio;       // output samples per input sample
  double cutoff;      // of the input's Nyquist frequency
  double half_width;  // kernel half-width, input samples
};

}  // namespace

PcmAudio resample(const PcmAudio& audio, int rate_hz) {
  if (audio.sample_rate_hz == rate_hz) return audio;
  const SincKernel kernel(audio.sample_rate_hz, rate_hz);
  const auto input_size = static_cast<std::int64_t>(audio.samples.size());
  PcmAudio out;
  out.sample_rate_hz = rate_hz;
  out.samples.resize(static_cast<std::size_t>(std::floor(double(input_size) * kernel.ratio)));
  for (std::size_t n = 0; n < out.samples.size(); ++n) {
    const auto i = static_cast<std::int64_t>(n);
    out.samples[n] = kernel.output(i, std::max<std::int64_t>(0, kernel.first_input(i)),
                                   std::min(input_size - 1, kernel.last_input(i)),
                                   [&](std::int64_t k) { return audio.samples[static_cast<std::size_t>(k)]; });
  }
  return out;
}

StreamingResampler::StreamingResampler(int from_hz, int to_hz) : from_hz_(from_hz), to_hz_(to_hz) {}

void StreamingResampler::push(std::span<const std::int16_t> samples, std::vector<std::int16_t>& out) {
  if (from_hz_ == to_hz_) {
    out.insert(out.end(), samples.begin(), samples.end());
    return;
  }
  held_.insert(held_.end(), samples.begin(), samples.end());
  received_ += static_cast<std::int64_t>(samples.size());
  emit(false, out);
}

void StreamingResampler::finish(std::vector<std::int16_t>& out) {
  if (from_hz_ != to_hz_) emit(true, out);
}

void StreamingResampler::emit(bool finishing, std::vector<std::int16_t>& out) {
  const SincKernel kernel(from_hz_, to_hz_);
  // resample() makes floor(input size × ratio) samples; each is made here once every input
  // sample it reads has come (or, at the end, with the kernel clamped as resample() clamps it).
  const auto total = static_cast<std::int64_t>(std::floor(double(received_) * kernel.ratio));
  for (; next_ < total; ++next_) {
    const std::int64_t last = kernel.last_input(next_);
    if (!finishing && last >= received_) break;
    const std::int64_t first = std::max<std::int64_t>(0, kernel.first_input(next_));
    out.push_back(kernel.output(next_, first, std::min(received_ - 1, last),
                                [&](std::int64_t k) { return held_[static_cast<std::size_t>(k - held_from_)]; }));
  }
  // Drop the input no later output sample reads.
  const std::int64_t keep_from = std::max<std::int64_t>(held_from_, kernel.first_input(next_));
  if (keep_from > held_from_) {
    held_.erase(held_.begin(), held_.begin() + std::min<std::int64_t>(keep_from - held_from_,
                                                                      static_cast<std::int64_t>(held_.size())));
    held_from_ = keep_from;
  }
}

std::string pcm_s16le_bytes(std::span<const std::int16_t> samples) {
  std::string bytes;
  bytes.reserve(samples.size() * 2);
  for (const std::int16_t sample : samples) {
    const auto u = static_cast<std::uint16_t>(sample);
    bytes.push_back(static_cast<char>(u & 0xFF));
    bytes.push_back(static_cast<char>(u >> 8));
  }
  return bytes;
}

void write_wav(std::ostream& out, const PcmAudio& audio) {
  const auto data_bytes = static_cast<std::uint32_t>(audio.samples.size() * 2);
  const auto u32 = [&](std::uint32_t v) {
    const char b[4] = {char(v & 0xFF), char((v >> 8) & 0xFF), char((v >> 16) & 0xFF), char(v >> 24)};
    out.write(b, 4);
  };
  const auto u16 = [&](std::uint16_t v) {
    const char b[2] = {char(v & 0xFF), char(v >> 8)};
    out.write(b, 2);
  };
  const auto rate = static_cast<std::uint32_t>(audio.sample_rate_hz);
  out.write("RIFF", 4);
  u32(36 + data_bytes);
  out.write("WAVEfmt ", 8);
  u32(16);
  u16(kFormatPcm);
  u16(1);  // channels
  u32(rate);
  u32(rate * 2);  // bytes per second
  u16(2);         // bytes per frame
  u16(16);        // bits per sample
  out.write("data", 4);
  u32(data_bytes);
  for (const std::int16_t s : audio.samples) u16(static_cast<std::uint16_t>(s));
}

void cover_audio(LabeledUtterance& utterance, std::int64_t audio_end_us, int fps) {
  // The grid's spacing is 10⁶/fps rounded, and it may restart at a closure, so a
  // silence one step (rounded up) plus 1 µs past the audio holds a grid point at or
  // after the audio's end, and the scheduler only emits grid points before a segment's end.
  const std::int64_t step_us = (1'000'000 + fps - 1) / fps;
  const std::int64_t wanted_end_us = audio_end_us + step_us + 1;
  const std::int64_t last_end_us = utterance.intervals.empty() ? 0 : utterance.intervals.back().end_us;
  if (last_end_us >= wanted_end_us) return;
  const int line = utterance.intervals.empty() ? 1 : utterance.intervals.back().line + 1;
  utterance.intervals.push_back({"", last_end_us, wanted_end_us, line});
}

}  // namespace lipsync::speech
