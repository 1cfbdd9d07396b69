// MBROLA .pho: "label duration_ms [position% pitch_hz]..." per phoneme, ';'
// starts a comment, a lone "#" is MBROLA's flush command. Only durations are
// written, so start times accumulate from 0. The pitch pairs are checked for
// shape (pairs of finite numbers) and otherwise ignored.
#include <string>

#include "formats/readers.hpp"
#include "formats/text.hpp"
#include "lipsync/error.hpp"

namespace lipsync::formats {

LabeledUtterance read_pho(std::string_view text, const std::string& source) {
  LabeledUtterance utterance{source, "sampa", {}};
  std::int64_t start_us = 0;
  for (const Line& line : split_lines(text)) {
    const std::string_view content = line.text.substr(0, line.text.find(';'));
    const std::vector<std::string_view> fields = split_fields(content);
    if (fields.empty() || (fields.size() == 1 && fields[0] == "#")) continue;
    if (fields.size() < 2) {
      throw InputError(source, line.number,
                       "expected \"label duration_ms [position% pitch_hz]...\", found " + excerpt(trim(content)));
    }
    const std::int64_t duration_us = milliseconds_field_to_us(fields[1], "duration_ms", source, line.number);
    if (fields.size() % 2 != 0) {
      throw InputError(source, line.number,
                       "pitch points come in pairs \"position% pitch_hz\", but an odd number of "
                       "values follows the duration: " +
                           excerpt(trim(content)));
    }
    for (std::size_t i = 2; i < fields.size(); i += 2) {
      std::string_view position = fields[i];
      if (position.ends_with('%')) position.remove_suffix(1);
      if (!parse_finite_double(position)) {
        throw InputError(source, line.number, "pitch position (percent) is not a number: " + excerpt(fields[i]));
      }
      if (!parse_finite_double(fields[i + 1])) {
        throw InputError(source, line.number, "pitch (Hz) is not a number: " + excerpt(fields[i + 1]));
      }
    }
    const std::int64_t end_us = checked_add_us(start_us, duration_us, source, line.number);
    utterance.intervals.push_back({std::string(fields[0]), start_us, end_us, line.number});
    start_us = end_us;
  }
  return utterance;
}

}  // namespace lipsync::formats
