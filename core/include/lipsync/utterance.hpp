// What the parsers produce: labelled time intervals as the source wrote them,
// before any mapping to the articulation model.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace lipsync {

/// One phoneme as written in the input.
struct LabeledInterval {
  std::string label;      ///< as written (trimmed); empty means silence
  std::int64_t start_us;  ///< start time, microseconds from utterance time 0
  std::int64_t end_us;    ///< end time, microseconds; end_us > start_us once validated
  int line = 0;           ///< 1-based source line (or phoneme index) for error messages
};

/// A parsed utterance file.
struct LabeledUtterance {
  std::string source;                      ///< file name for messages
  std::string phone_set;                   ///< phone set the file declares, or "" when it does not say
  std::vector<LabeledInterval> intervals;  ///< in file order (not yet validated)
};

}  // namespace lipsync
