// Festival / CMU ARCTIC .lab: free header lines ("separator ;", "nfields 1")
// up to a line that is "#", then "end_time colour label" per segment, where the
// colour is an integer Xwaves used for display. Only end times are written: a
// segment starts where the previous one ended, the first one at 0. A file with
// no "#" line is read as data from its first line.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>

#include "formats/readers.hpp"
#include "formats/text.hpp"
#include "lipsync/error.hpp"

namespace lipsync::formats {

LabeledUtterance read_lab(std::string_view text, const std::string& source) {
  const std::vector<Line> lines = split_lines(text);
  auto first_data = std::find_if(lines.begin(), lines.end(), [](const Line& line) { return trim(line.text) == "#"; });
  first_data = first_data == lines.end() ? lines.begin() : first_data + 1;

  LabeledUtterance utterance{source, "radio", {}};
  std::int64_t previous_end_us = 0;
  for (auto line = first_data; line != lines.end(); ++line) {
    const std::vector<std::string_view> fields = split_fields(line->text);
    if (fields.empty()) continue;
    if (fields.size() != 3) {
      throw InputError(source, line->number,
                       "expected \"end_time colour label\" (or a \"#\" line ending the header), "
                       "found " +
                           excerpt(trim(line->text)));
    }
    const std::int64_t end_us = seconds_field_to_us(fields[0], "end_time", source, line->number);
    const std::string_view colour = fields[1].starts_with('-') ? fields[1].substr(1) : fields[1];
    if (!parse_count(colour, std::numeric_limits<std::int64_t>::max())) {
      throw InputError(source, line->number, "colour (second field) is not an integer: " + excerpt(fields[1]));
    }
    utterance.intervals.push_back({std::string(fields[2]), previous_end_us, end_us, line->number});
    previous_end_us = end_us;
  }
  return utterance;
}

}  // namespace lipsync::formats
