// Rendering a track from model segments: offline (all segments known) and
// streaming (segments arrive one at a time).
//
// Both paths schedule frames with FrameScheduler and evaluate them with
// CoarticulationEvaluator on the same window of segments (the frame's segment,
// up to 7 before and up to `lookahead` after), so with lookahead 7 the stream
// is identical, value for value, to the offline render, however the input is
// chunked. The streaming renderer keeps only the last 2·7+1 segments and the
// frames still waiting for their lookahead: memory is bounded by the window.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "lipsync/coarticulation.hpp"
#include "lipsync/keyframes.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/setting_ranges.hpp"
#include "lipsync/track.hpp"

namespace lipsync {

struct RenderOptions {
  int fps = static_cast<int>(kFpsSetting.default_value);  ///< kFpsSetting: 1 to 240
  bool fixed_rate = false;                                ///< uniform grid only
  /// Segments after a frame's own that must be known before it is emitted
  /// (kLookaheadSetting: 0 to 7). 7 is exact; smaller values emit sooner and approximate.
  int lookahead = static_cast<int>(kLookaheadSetting.default_value);
};

/// Renders a whole utterance. Throws SettingError (a std::invalid_argument) for bad options.
Track render_track(const ArticulationModel& model, const std::vector<Segment>& segments,
                   const RenderOptions& options = {});
/// The same with the model's evaluator tables built once beforehand (a server
/// rendering many utterances with one model).
Track render_track(std::shared_ptr<const CoarticulationTables> tables, const std::vector<Segment>& segments,
                   const RenderOptions& options = {});

class StreamingRenderer {
 public:
  /// Throws SettingError (a std::invalid_argument) for bad options.
  StreamingRenderer(const ArticulationModel& model, const RenderOptions& options = {});
  /// The same with the model's evaluator tables built once beforehand.
  StreamingRenderer(std::shared_ptr<const CoarticulationTables> tables, const RenderOptions& options = {});

  /// Adds the next segment (contiguous with the previous one) and appends every
  /// frame that became computable to `out` (which must have this model's
  /// channel_count).
  void push(const Segment& segment, Track& out);
  /// Ends the utterance: appends every remaining frame.
  void finish(Track& out);

  /// Frames scheduled but not yet emitted (waiting for lookahead).
  std::size_t pending_frames() const { return pending_.size(); }
  /// Segments held in memory.
  std::size_t held_segments() const { return window_.size(); }

 private:
  void emit_ready(Track& out, bool finishing);

  RenderOptions options_;
  FrameScheduler scheduler_;
  CoarticulationEvaluator evaluator_;
  // Segments [first_index_, pushed_): contiguous, so that a frame's window is a
  // span of them. At most 2 · kWindowRadius + 1 between calls, one more while push
  // adds a segment before emitting: each emission drops the ones no future frame
  // can see (a short move to the front), so the reserved room never grows.
  std::vector<Segment> window_;
  std::size_t first_index_ = 0;            // global index of window_.front()
  std::size_t pushed_ = 0;                 // segments pushed so far
  std::vector<ScheduledFrame> scheduled_;  // scratch for the scheduler
  std::vector<ScheduledFrame> pending_;    // in time order; emitted from the front
  bool finished_ = false;
};

}  // namespace lipsync
