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

PcmAudio resample(const PcmAudio& audio, int rate_hz) {
  if (audio.sample_rate_hz == rate_hz) return audio;
  constexpr double kZeroCrossings = 16;
  const double ratio = double(rate_hz) / audio.sample_rate_hz;  // output samples per input sample
  const double cutoff = 0.95 * std::min(1.0, ratio);            // of the input's Nyquist frequency
  const double half_width = kZeroCrossings / cutoff;            // kernel half-width, input samples
  const auto input_size = static_cast<std::int64_t>(audio.samples.size());
  PcmAudio out;
  out.sample_rate_hz = rate_hz;
  out.samples.resize(static_cast<std::size_t>(std::floor(double(input_size) * ratio)));
  for (std::size_t n = 0; n < out.samples.size(); ++n) {
    const double centre = double(n) / ratio;  // the output sample's time, in input samples
    const auto first = std::max<std::int64_t>(0, static_cast<std::int64_t>(std::ceil(centre - half_width)));
    const auto last =
        std::min<std::int64_t>(input_size - 1, static_cast<std::int64_t>(std::floor(centre + half_width)));
    double sum = 0;
    for (std::int64_t k = first; k <= last; ++k) {
      const double x = double(k) - centre;
      const double arg = std::numbers::pi * cutoff * x;
      const double sinc = x == 0 ? 1.0 : std::sin(arg) / arg;
      const double phase = std::numbers::pi * (x / half_width + 1.0);  // Blackman window over [-w, w]
      const double window = 0.42 - 0.5 * std::cos(phase) + 0.08 * std::cos(2 * phase);
      sum += audio.samples[static_cast<std::size_t>(k)] * cutoff * sinc * window;
    }
    out.samples[n] = to_int16(sum / 32768.0);
  }
  return out;
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
