// Frame placement after Section 3.2–3.3 (rules in lipsync/keyframes.hpp).
#include "lipsync/keyframes.hpp"

#include <algorithm>
#include <cmath>

namespace lipsync {

FrameScheduler::FrameScheduler(const ArticulationModel& model, ScheduleOptions options)
    : model_(&model), options_(options) {
  checked_fps(options_.fps, "fps");
}

std::int64_t FrameScheduler::grid_time(std::int64_t i) const {
  // anchor + round(i · 10⁶ / fps), exact in integers: no drift however long.
  return anchor_us_ + (i * 1'000'000 + options_.fps / 2) / options_.fps;
}

void FrameScheduler::add_segment(const Segment& segment, std::size_t index, std::vector<ScheduledFrame>& out) {
  const std::size_t before = out.size();
  const auto emit = [&](std::int64_t t_us, FrameKind kind) {
    out.push_back({t_us, kind, index});
    last_emitted_us_ = t_us;
  };
  last_index_ = index;
  last_end_us_ = segment.end_us;
  const bool is_closure = !options_.fixed_rate && segment.phoneme_class == PhonemeClass::closure;

  if (in_closure_) {
    // The previous segment was a closure: a key frame where it ends, and the
    // grid restarts from here (Fig. 3). If this segment is a closure too, the
    // same instant is its start.
    emit(segment.start_us, is_closure ? FrameKind::closure_start : FrameKind::closure_end);
    anchor_us_ = segment.start_us;
    next_index_ = 1;
    in_closure_ = false;
  }
  if (is_closure) {
    if (out.size() == before) emit(segment.start_us, FrameKind::closure_start);
    in_closure_ = true;  // no uniform frames inside a closure
    return;
  }

  while (grid_time(next_index_) < segment.start_us) ++next_index_;
  for (std::int64_t t = grid_time(next_index_); t < segment.end_us; t = grid_time(++next_index_)) {
    emit(t, FrameKind::uniform);
  }
  if (out.size() == before && !options_.fixed_rate) {
    // A segment shorter than the sampling interval: one frame at the peak of
    // its dominance, clamped into the segment (Section 3.3, Fig. 4).
    const PhonemeSpec& spec = model_->phoneme(segment.phoneme);
    std::int64_t peak_us = segment.start_us;
    if (segment.phoneme_class != PhonemeClass::release) {
      peak_us = (segment.start_us + segment.end_us) / 2 - std::llround(spec.keyframe_t_off_s * 1e6);
    }
    emit(std::clamp(peak_us, segment.start_us, segment.end_us - 1), FrameKind::short_segment);
  }
}

void FrameScheduler::finish(std::vector<ScheduledFrame>& out) {
  if (in_closure_) {
    out.push_back({last_end_us_, FrameKind::closure_end, last_index_});
    last_emitted_us_ = last_end_us_;
    in_closure_ = false;
  }
}

}  // namespace lipsync
