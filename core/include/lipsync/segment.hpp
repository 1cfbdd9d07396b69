// From labelled intervals to model segments.
//
// SegmentBuilder is the one place where input timing is validated and where
// labels become model phonemes. It works one interval at a time, so a file and
// a live phoneme stream go through exactly the same rules:
//   - labels map through the phone set (unknown label: error naming the set);
//   - a gap between intervals becomes a silence segment, and so does a leading
//     gap from utterance time 0 to the first interval;
//   - overlapping or reversed intervals, zero or negative durations and times
//     that go backwards are errors naming the line (or phoneme index) and value;
//   - a release phoneme (/p/, /b/) that does not follow its own closure is split
//     into a closure part and a release part (closure_fraction of its duration,
//     at least 1 µs each), so that key-frame rules apply to every input format.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/model.hpp"
#include "lipsync/setting_ranges.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync {

class PhoneSet;

/// A stretch of the utterance assigned to one model phoneme. Segments are
/// contiguous: each one starts where the previous one ends.
struct Segment {
  int phoneme = 0;  ///< index into ArticulationModel::phonemes()
  PhonemeClass phoneme_class = PhonemeClass::silence;
  std::int64_t start_us = 0;
  std::int64_t end_us = 0;
  int source_line = 0;  ///< line or phoneme index it came from (0: inserted silence)
};

struct SegmentOptions {
  /// Share of a /p b/ segment given to its closure when the input has no separate
  /// closure label. Bilabial stop closures take most of the stop's duration
  /// (about 60 to 70 %); 0.6 is the default. Range (0, 1).
  double closure_fraction = kDefaultClosureFraction;
};

class SegmentBuilder {
 public:
  /// `source` names the input in error messages ("speech.TextGrid", "phoneme stream").
  SegmentBuilder(const ArticulationModel& model, const PhoneSet& phone_set, std::string source,
                 SegmentOptions options = {});

  /// Validates one interval and appends the segments it yields (a gap silence,
  /// a closure, the phoneme) to `out`. Throws InputError on bad input; on throw,
  /// the builder is unchanged and nothing was appended.
  void push(const LabeledInterval& interval, std::vector<Segment>& out) {
    push(interval.label, interval.start_us, interval.end_us, interval.line, out);
  }
  /// The same for a label held elsewhere (a streamed phoneme's), without copying it.
  void push(std::string_view label, std::int64_t start_us, std::int64_t end_us, int line, std::vector<Segment>& out);

  /// End time of the last segment so far (0 before the first).
  std::int64_t end_us() const { return end_us_; }

 private:
  // Pointers, so that a builder can be assigned (LiveRenderer reuses one).
  const ArticulationModel* model_;
  const PhoneSet* phone_set_;
  std::string source_;
  SegmentOptions options_;
  std::int64_t end_us_ = 0;
  int last_phoneme_ = -1;
  int last_line_ = 0;
};

/// Builds all segments of an utterance (convenience over SegmentBuilder).
/// Throws InputError if the utterance has no interval.
std::vector<Segment> build_segments(const LabeledUtterance& utterance, const ArticulationModel& model,
                                    const PhoneSet& phone_set, SegmentOptions options = {});

}  // namespace lipsync
