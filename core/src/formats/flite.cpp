// flite -psdur output: "label:end_seconds" tokens separated by white space,
// usually all on one line, start = previous end (the first one starts at 0).
// Each interval remembers the line its token is on.
#include <string>

#include "formats/readers.hpp"
#include "formats/text.hpp"
#include "lipsync/error.hpp"

namespace lipsync::formats {

LabeledUtterance read_flite(std::string_view text, const std::string& source) {
  LabeledUtterance utterance{source, "radio", {}};
  std::int64_t previous_end_us = 0;
  for (const Line& line : split_lines(text)) {
    for (const std::string_view token : split_fields(line.text)) {
      const std::size_t colon = token.rfind(':');
      if (colon == std::string_view::npos) {
        throw InputError(source, line.number, "expected \"label:end_seconds\", found " + excerpt(token));
      }
      const std::string_view label = token.substr(0, colon);
      if (label.empty()) {
        throw InputError(source, line.number, "missing label before ':' in " + excerpt(token));
      }
      const std::int64_t end_us =
          seconds_field_to_us(token.substr(colon + 1), "end time of " + excerpt(label), source, line.number);
      utterance.intervals.push_back({std::string(label), previous_end_us, end_us, line.number});
      previous_end_us = end_us;
    }
  }
  return utterance;
}

}  // namespace lipsync::formats
