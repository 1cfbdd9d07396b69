// TIMIT .PHN: one "start_sample end_sample label" line per phone, sample
// numbers at a known rate (16 kHz in TIMIT itself). Samples become
// microseconds in integer arithmetic, rounded half up: no float in between.
#include <string>

#include "formats/readers.hpp"
#include "formats/text.hpp"
#include "lipsync/error.hpp"
#include "lipsync/time.hpp"

namespace lipsync::formats {
namespace {

std::int64_t samples_to_us(std::string_view text, std::string_view field, int rate_hz, const std::string& source,
                           int line) {
  const std::string what(field);
  if (!is_decimal_number(text)) {
    throw InputError(source, line, what + " is not a number: " + excerpt(text));
  }
  if (text.starts_with('-') && text.find_first_of("123456789") != std::string_view::npos) {
    throw InputError(source, line, what + " is negative: " + excerpt(text));
  }
  if (text.find_first_of(".eE") != std::string_view::npos) {
    throw InputError(source, line, what + " is not a whole number of samples: " + excerpt(text));
  }
  const std::int64_t rate = rate_hz;
  const std::int64_t max_samples = (kMaxTimeUs / kMicrosPerSecond + 1) * rate;
  const std::string_view digits = text.starts_with('-') ? text.substr(1) : text;
  const std::optional<std::int64_t> samples = parse_count(digits, max_samples);
  std::int64_t time_us = kMaxTimeUs + 1;
  if (samples) {
    time_us = *samples / rate * kMicrosPerSecond + (*samples % rate * kMicrosPerSecond + rate / 2) / rate;
  }
  if (time_us > kMaxTimeUs) {
    throw InputError(source, line,
                     what + " is beyond 24 hours at " + std::to_string(rate_hz) + " Hz: " + excerpt(text) +
                         " (check the sample rate)");
  }
  return time_us;
}

}  // namespace

LabeledUtterance read_timit(std::string_view text, const std::string& source, int sample_rate_hz) {
  if (sample_rate_hz <= 0) {
    throw InputError(source, 0,
                     "the TIMIT sample rate must be a positive number of hertz, got " + std::to_string(sample_rate_hz));
  }
  LabeledUtterance utterance{source, "timit", {}};
  for (const Line& line : split_lines(text)) {
    const std::vector<std::string_view> fields = split_fields(line.text);
    if (fields.empty()) continue;
    if (fields.size() != 3) {
      throw InputError(source, line.number,
                       "expected \"start_sample end_sample label\", found " + excerpt(trim(line.text)));
    }
    const std::int64_t start_us = samples_to_us(fields[0], "start_sample", sample_rate_hz, source, line.number);
    const std::int64_t end_us = samples_to_us(fields[1], "end_sample", sample_rate_hz, source, line.number);
    utterance.intervals.push_back({std::string(fields[2]), start_us, end_us, line.number});
  }
  return utterance;
}

}  // namespace lipsync::formats
