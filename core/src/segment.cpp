// Validation of input timing and mapping of labels to model segments
// (the rules are listed in lipsync/segment.hpp).
#include "lipsync/segment.hpp"

#include <algorithm>
#include <cmath>

#include "lipsync/error.hpp"
#include "lipsync/excerpt.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/time.hpp"

namespace lipsync {
namespace {

std::string seconds(std::int64_t time_us) { return format_seconds(time_us) + " s"; }

}  // namespace

SegmentBuilder::SegmentBuilder(const ArticulationModel& model, const PhoneSet& phone_set, std::string source,
                               SegmentOptions options)
    : model_(&model), phone_set_(&phone_set), source_(std::move(source)), options_(options) {
  checked_closure_fraction(options_.closure_fraction, "closure_fraction");
}

void SegmentBuilder::push(std::string_view label, std::int64_t start_us, std::int64_t end_us, int line,
                          std::vector<Segment>& out) {
  const auto fail = [&](const std::string& message) {
    throw InputError(source_, line, "phoneme " + excerpt(label) + ": " + message);
  };
  if (start_us < 0) fail("start time " + seconds(start_us) + " is negative");
  if (end_us > kMaxTimeUs || start_us > kMaxTimeUs) {
    fail("time " + seconds(std::max(start_us, end_us)) + " is beyond 24 hours; are the times in the right unit?");
  }
  if (end_us == start_us) {
    fail("zero duration (starts and ends at " + seconds(start_us) + ")");
  }
  if (end_us < start_us) {
    fail("ends (" + seconds(end_us) + ") before it starts (" + seconds(start_us) + ")");
  }
  if (start_us < end_us_) {
    std::string previous = last_line_ > 0 ? " (line " + std::to_string(last_line_) + ")" : "";
    fail("starts at " + seconds(start_us) + ", before the previous phoneme" + previous + " ends at " +
         seconds(end_us_) + ": phonemes must be in time order and must not overlap");
  }
  const auto phoneme = phone_set_->lookup(label);
  if (!phoneme) {
    if (const std::optional<std::string> phones = phone_set_->several_phones(label)) {
      fail("several phones in one interval (" + *phones + " in phone set '" + phone_set_->name() +
           "'), with no tie bar and no vowel: an interval holds one phone (mark an affricate with a "
           "tie bar, t͡s)");
    }
    fail("unknown label in phone set '" + phone_set_->name() + "'");
  }

  const PhonemeSpec& spec = model_->phoneme(*phoneme);
  if (start_us > end_us_) {
    out.push_back({model_->silence_phoneme(), PhonemeClass::silence, end_us_, start_us, 0});
    last_phoneme_ = model_->silence_phoneme();
  }
  std::int64_t phoneme_start_us = start_us;  // after its closure, if one is split off
  const std::int64_t duration_us = end_us - start_us;
  if (spec.phoneme_class == PhonemeClass::release && spec.closure_phoneme >= 0 &&
      last_phoneme_ != spec.closure_phoneme && duration_us >= 2) {
    auto closure_us =
        static_cast<std::int64_t>(std::llround(static_cast<double>(duration_us) * options_.closure_fraction));
    closure_us = std::clamp<std::int64_t>(closure_us, 1, duration_us - 1);
    out.push_back({spec.closure_phoneme, PhonemeClass::closure, start_us, start_us + closure_us, line});
    phoneme_start_us += closure_us;
  }
  out.push_back({*phoneme, spec.phoneme_class, phoneme_start_us, end_us, line});
  last_phoneme_ = *phoneme;
  last_line_ = line;
  end_us_ = end_us;
}

std::vector<Segment> build_segments(const LabeledUtterance& utterance, const ArticulationModel& model,
                                    const PhoneSet& phone_set, SegmentOptions options) {
  if (utterance.intervals.empty()) {
    throw InputError(utterance.source, 0, "the utterance has no phonemes");
  }
  SegmentBuilder builder(model, phone_set, utterance.source, options);
  std::vector<Segment> segments;
  segments.reserve(utterance.intervals.size() + utterance.intervals.size() / 4 + 1);
  for (const LabeledInterval& interval : utterance.intervals) builder.push(interval, segments);
  return segments;
}

}  // namespace lipsync
