// Segments of the built-in model from ARPAbet phonemes and their durations, back to back from 0:
// the short hand-written utterances of the viseme and Moho tests.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <utility>
#include <vector>

#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync::testing {

/// {{"sil", 100}, {"aa", 172}, ...}: each phoneme lasting its milliseconds, after the one before.
inline std::vector<Segment> timed_segments(std::initializer_list<std::pair<const char*, int>> phonemes) {
  const ArticulationModel& model = ArticulationModel::builtin();
  LabeledUtterance labeled;
  labeled.source = "test";
  std::int64_t t = 0;
  for (const auto& [label, ms] : phonemes) {
    labeled.intervals.push_back({label, t, t + ms * 1000});
    t += ms * 1000;
  }
  return build_segments(labeled, model, *PhoneSet::builtin("arpabet", model));
}

}  // namespace lipsync::testing
