// Shared checks of the libFuzzer targets (tests/fuzz, docs/security.md).
//
// Each target feeds the fuzzer's bytes to one reader and holds it to its
// contract: it returns, or throws the project's documented error type (caught
// by the target), and what it returns obeys the invariants checked here. Any
// other exception escapes and libFuzzer reports it; a broken invariant aborts
// with a message naming it, so each finding reads as one line.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>
#include <vector>

#include "lipsync/error.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/time.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync::fuzz {

/// Aborts (a libFuzzer finding) with `what` when `condition` is false.
inline void check(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "fuzz invariant broken: %s\n", what);
    std::abort();
  }
}

inline std::string_view bytes(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

/// Segments from SegmentBuilder: at least one, from utterance time 0, each one
/// non-empty and starting where the previous one ended, naming a model phoneme.
inline void check_segments(const std::vector<Segment>& segments, const ArticulationModel& model) {
  std::int64_t previous_end_us = 0;
  for (const Segment& segment : segments) {
    check(segment.start_us == previous_end_us, "segments are contiguous from 0");
    check(segment.end_us > segment.start_us, "segments are not empty");
    check(segment.phoneme >= 0 && static_cast<std::size_t>(segment.phoneme) < model.phonemes().size(),
          "segments name a model phoneme");
    check(segment.phoneme_class == model.phoneme(segment.phoneme).phoneme_class, "a segment's class is its phoneme's");
    previous_end_us = segment.end_us;
  }
}

/// A parsed utterance: every time within ±kMaxTimeUs; then, mapped through its
/// declared phone set (or the detected one) onto the built-in model, either
/// contiguous segments or an InputError.
inline void check_utterance(const LabeledUtterance& utterance) {
  for (const LabeledInterval& interval : utterance.intervals) {
    check(interval.start_us >= -kMaxTimeUs && interval.start_us <= kMaxTimeUs, "start within kMaxTimeUs");
    check(interval.end_us >= -kMaxTimeUs && interval.end_us <= kMaxTimeUs, "end within kMaxTimeUs");
  }
  const ArticulationModel& model = ArticulationModel::builtin();
  static const std::vector<PhoneSet> phone_sets = PhoneSet::builtin_all(model);
  const PhoneSet* phone_set = nullptr;
  if (!utterance.phone_set.empty()) {
    for (const PhoneSet& candidate : phone_sets) {
      if (candidate.name() == utterance.phone_set) phone_set = &candidate;
    }
    if (phone_set == nullptr) return;  // the CLI refuses an unknown phone set by name
  } else {
    std::vector<std::string_view> labels;
    for (const LabeledInterval& interval : utterance.intervals) labels.push_back(interval.label);
    phone_set = &detect_phone_set(phone_sets, labels);
  }
  try {
    check_segments(build_segments(utterance, model, *phone_set), model);
  } catch (const InputError&) {
  }
}

}  // namespace lipsync::fuzz
