// The synthesis worker's request and answer as bytes (synthesis_wire.hpp): fixed-size values as
// their bytes, strings as a 64-bit length and the bytes, the samples as one block, then the words'
// starts and the notes.
#include "synthesis_wire.hpp"

#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "espeak_synthesis.hpp"
#include "lipsync/error.hpp"

namespace lipsync::speech::detail {
namespace {

constexpr char kOk = 0;
constexpr char kInputError = 1;
constexpr char kOtherError = 2;

template <typename T>
void put(std::string& out, const T& value) {
  out.append(reinterpret_cast<const char*>(&value), sizeof value);
}

void put_string(std::string& out, const std::string& text) {
  put(out, static_cast<std::uint64_t>(text.size()));
  out += text;
}

/// Reads what put() and put_string() wrote; std::runtime_error if it is cut short.
class Decoder {
 public:
  explicit Decoder(std::string_view bytes) : bytes_(bytes) {}
  template <typename T>
  T get() {
    T value;
    std::memcpy(&value, take(sizeof value).data(), sizeof value);
    return value;
  }
  std::string get_string() { return std::string(take(get<std::uint64_t>())); }
  std::string_view take(std::size_t size) {
    if (size > bytes_.size()) throw std::runtime_error("espeak-ng: the synthesis process's answer is cut short");
    const std::string_view part = bytes_.substr(0, size);
    bytes_.remove_prefix(size);
    return part;
  }

 private:
  std::string_view bytes_;
};

}  // namespace

std::string encode_request(std::string_view text, const SynthesisOptions& options) {
  std::string out;
  put_string(out, std::string(text));
  put_string(out, options.voice);
  put(out, options.words_per_minute);
  return out;
}

SynthesisRequest decode_request(std::string_view bytes) {
  Decoder in(bytes);
  SynthesisRequest request;
  request.text = in.get_string();
  request.options.voice = in.get_string();
  request.options.words_per_minute = in.get<int>();
  return request;
}

std::string encode_answer(const Synthesis& synthesis) {
  std::string out(1, kOk);
  put_string(out, synthesis.phonemes.phone_set);
  put(out, synthesis.audio.sample_rate_hz);
  put(out, static_cast<std::uint64_t>(synthesis.audio.samples.size()));
  out.append(reinterpret_cast<const char*>(synthesis.audio.samples.data()),
             synthesis.audio.samples.size() * sizeof(std::int16_t));
  put(out, static_cast<std::uint64_t>(synthesis.phonemes.intervals.size()));
  for (const LabeledInterval& interval : synthesis.phonemes.intervals) {
    put_string(out, interval.label);
    put(out, interval.start_us);
    put(out, interval.end_us);
    put(out, interval.line);
  }
  put(out, static_cast<std::uint64_t>(synthesis.word_starts_us.size()));
  for (const std::int64_t start_us : synthesis.word_starts_us) put(out, start_us);
  put(out, static_cast<std::uint64_t>(synthesis.notes.size()));
  for (const std::string& note : synthesis.notes) put_string(out, note);
  return out;
}

std::string encode_input_error_answer(const std::string& message) {
  std::string out(1, kInputError);
  put_string(out, message);
  return out;
}

std::string encode_other_error_answer(const std::string& message) {
  std::string out(1, kOtherError);
  put_string(out, message);
  return out;
}

Synthesis decode_answer(std::string_view bytes) {
  Decoder in(bytes);
  const char kind = in.get<char>();
  if (kind == kInputError) throw InputError(std::string(kEspeakSource), 0, in.get_string());
  if (kind != kOk) throw std::runtime_error("espeak-ng: " + in.get_string());
  Synthesis result;
  result.phonemes.phone_set = in.get_string();
  result.audio.sample_rate_hz = in.get<int>();
  result.audio.samples.resize(in.get<std::uint64_t>());
  const std::string_view samples = in.take(result.audio.samples.size() * sizeof(std::int16_t));
  std::memcpy(result.audio.samples.data(), samples.data(), samples.size());
  result.phonemes.source = std::string(kEspeakSource);
  const auto count = in.get<std::uint64_t>();
  for (std::uint64_t i = 0; i < count; ++i) {
    LabeledInterval interval;
    interval.label = in.get_string();
    interval.start_us = in.get<std::int64_t>();
    interval.end_us = in.get<std::int64_t>();
    interval.line = in.get<int>();
    result.phonemes.intervals.push_back(std::move(interval));
  }
  const auto words = in.get<std::uint64_t>();
  for (std::uint64_t i = 0; i < words; ++i) result.word_starts_us.push_back(in.get<std::int64_t>());
  const auto notes = in.get<std::uint64_t>();
  for (std::uint64_t i = 0; i < notes; ++i) result.notes.push_back(in.get_string());
  return result;
}

}  // namespace lipsync::speech::detail
