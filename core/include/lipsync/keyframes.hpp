// Where frames are taken (paper Section 3.2, 3.3, figures 3–5).
//
// A uniform grid at `fps` runs from utterance time 0. At the start of a closure
// (/p b/ closure parts, /m f v/) a closure_start frame is taken and the grid
// pauses; at the closure's end (the next segment's start) a closure_end frame
// is taken and the grid restarts from it. Any other segment that no frame falls
// into gets a short_segment frame at the peak of its dominance, clamped into the
// segment, without moving the grid. In fixed-rate mode only the grid is used.
//
// FrameScheduler is incremental: it is told each segment once, in order, and
// reports the frames that fall into it, so a stream and a whole file get the
// same schedule. Grid times are exact: anchor + round(i · 10^6 / fps) µs.
#pragma once

#include <cstdint>
#include <vector>

#include "lipsync/segment.hpp"
#include "lipsync/setting_ranges.hpp"
#include "lipsync/track.hpp"

namespace lipsync {

struct ScheduleOptions {
  int fps = static_cast<int>(kFpsSetting.default_value);  ///< kFpsSetting: 1 to 240
  bool fixed_rate = false;                                ///< uniform grid only, no key frames
};

struct ScheduledFrame {
  std::int64_t t_us;
  FrameKind kind;
  std::size_t segment;  ///< index of the segment that contains t (for t == end of the last segment: the last)
};

class FrameScheduler {
 public:
  /// Throws SettingError (a std::invalid_argument) if fps is outside kFpsSetting.
  FrameScheduler(const ArticulationModel& model, ScheduleOptions options);

  /// Appends the frames whose time lies in `segment` (index `index`, the segments
  /// numbered from 0 in order) to `out`, in time order.
  void add_segment(const Segment& segment, std::size_t index, std::vector<ScheduledFrame>& out);
  /// Appends the frames at the very end of the utterance (the closure_end frame
  /// of a closure that ends the utterance). Call once after the last segment.
  void finish(std::vector<ScheduledFrame>& out);

 private:
  std::int64_t grid_time(std::int64_t i) const;

  const ArticulationModel* model_;  // a pointer, so that a scheduler can be assigned (LiveRenderer reuses one)
  ScheduleOptions options_;
  std::int64_t anchor_us_ = 0;   // grid restart point
  std::int64_t next_index_ = 0;  // next grid index not yet emitted
  bool in_closure_ = false;      // the last segment was a closure
  std::int64_t last_emitted_us_ = -1;
  std::size_t last_index_ = 0;
  std::int64_t last_end_us_ = 0;
};

}  // namespace lipsync
