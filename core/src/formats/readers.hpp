// One reader per input format. Each takes UTF-8 text (already decoded by
// parse_utterance) and returns the intervals as written, with the 1-based line
// (or phoneme index) of each one; checks are syntax and values only.
#pragma once

#include <string>
#include <string_view>

#include "lipsync/utterance.hpp"

namespace lipsync::formats {

LabeledUtterance read_json_utterance(std::string_view text, const std::string& source);
LabeledUtterance read_textgrid(std::string_view text, const std::string& source, std::string_view tier_name);
LabeledUtterance read_timit(std::string_view text, const std::string& source, int sample_rate_hz);
LabeledUtterance read_lab(std::string_view text, const std::string& source);
LabeledUtterance read_pho(std::string_view text, const std::string& source);
LabeledUtterance read_flite(std::string_view text, const std::string& source);

}  // namespace lipsync::formats
