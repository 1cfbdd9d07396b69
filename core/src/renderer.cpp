// Offline and streaming rendering share the scheduler and the evaluator, and
// hand the evaluator the same window of segments for each frame (all the frames
// of a segment in one call, each computed on its own): that is what
// makes the stream identical to the offline render (lipsync/renderer.hpp).
#include "lipsync/renderer.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace lipsync {
namespace {

static_assert(kLookaheadSetting.max == kWindowRadius && kLookaheadSetting.default_value == kWindowRadius,
              "the exact lookahead is the whole coarticulation window");

ScheduleOptions schedule_options(const RenderOptions& options) {
  checked_lookahead(options.lookahead, "lookahead");
  return {options.fps, options.fixed_rate};
}

/// Global index range [first, last] of the segments a frame in segment
/// `frame_segment` sees, given `known` segments so far.
struct WindowRange {
  std::size_t first;
  std::size_t last;
};

WindowRange window_range(std::size_t frame_segment, std::size_t known, int lookahead) {
  const std::size_t first = frame_segment >= kWindowRadius ? frame_segment - kWindowRadius : 0;
  const std::size_t last = std::min(known - 1, frame_segment + static_cast<std::size_t>(lookahead));
  return {first, last};
}

/// What the phonemes of `window` say about the frame at `t_us` in window[current]
/// (FrameArticulation): the closures whose hold contains it, and its distance to speech in a pause.
/// Both renderers hand the same window for a frame, so they agree on this too.
FrameArticulation articulation_at(std::span<const Segment> window, std::size_t current, std::int64_t t_us) {
  FrameArticulation out;
  const auto holds = [t_us](const Segment& s) {
    return s.phoneme_class == PhonemeClass::closure && s.start_us <= t_us && t_us <= s.end_us;
  };
  if (current > 0 && holds(window[current - 1])) out.closure = window[current - 1].phoneme;
  if (holds(window[current])) {
    (out.closure == FrameArticulation::kNoPhoneme ? out.closure : out.meeting_closure) = window[current].phoneme;
  }
  if (window[current].phoneme_class == PhonemeClass::silence) {
    out.pause_us = std::numeric_limits<std::int64_t>::max();
    for (std::size_t s = current; s-- > 0;) {
      if (window[s].phoneme_class == PhonemeClass::silence) continue;
      out.pause_us = t_us - window[s].end_us;
      break;
    }
    for (std::size_t s = current + 1; s < window.size(); ++s) {
      if (window[s].phoneme_class == PhonemeClass::silence) continue;
      out.pause_us = std::min(out.pause_us, window[s].start_us - t_us);
      break;
    }
  }
  return out;
}

/// Appends the frames [begin, end), all in segment window[current], to `out`:
/// one call of the evaluator for all of them.
template <typename FrameIterator>
void append_frames(Track& out, FrameIterator begin, FrameIterator end, CoarticulationEvaluator& evaluator,
                   std::span<const Segment> window, std::size_t current) {
  const std::size_t first_frame = out.t_us.size();
  for (FrameIterator frame = begin; frame != end; ++frame) {
    out.t_us.push_back(frame->t_us);
    out.kinds.push_back(frame->kind);
    out.articulation.push_back(articulation_at(window, current, frame->t_us));
  }
  const std::size_t count = out.t_us.size() - first_frame;
  const std::size_t offset = out.values.size();
  out.values.resize(offset + count * out.channel_count);
  evaluator.evaluate(window, current, std::span<const std::int64_t>(out.t_us).subspan(first_frame, count),
                     std::span<float>(out.values).subspan(offset));
}

/// The end of the run of frames from `begin` that lie in the same segment.
template <typename FrameIterator>
FrameIterator same_segment_end(FrameIterator begin, FrameIterator end) {
  FrameIterator frame = begin;
  while (frame != end && frame->segment == begin->segment) ++frame;
  return frame;
}

}  // namespace

Track render_track(const ArticulationModel& model, const std::vector<Segment>& segments, const RenderOptions& options) {
  return render_track(std::make_shared<const CoarticulationTables>(model), segments, options);
}

Track render_track(std::shared_ptr<const CoarticulationTables> tables, const std::vector<Segment>& segments,
                   const RenderOptions& options) {
  const ArticulationModel& model = tables->model();
  FrameScheduler scheduler(model, schedule_options(options));
  std::vector<ScheduledFrame> frames;
  for (std::size_t i = 0; i < segments.size(); ++i) scheduler.add_segment(segments[i], i, frames);
  scheduler.finish(frames);

  Track track;
  track.channel_count = model.channel_count();
  track.fps = options.fps;
  track.t_us.reserve(frames.size());
  track.kinds.reserve(frames.size());
  track.articulation.reserve(frames.size());
  track.values.reserve(frames.size() * track.channel_count);
  CoarticulationEvaluator evaluator(std::move(tables));
  const std::span<const Segment> all(segments);
  for (auto run = frames.cbegin(); run != frames.cend();) {
    const auto run_end = same_segment_end(run, frames.cend());
    const auto [first, last] = window_range(run->segment, segments.size(), options.lookahead);
    append_frames(track, run, run_end, evaluator, all.subspan(first, last - first + 1), run->segment - first);
    run = run_end;
  }
  return track;
}

StreamingRenderer::StreamingRenderer(const ArticulationModel& model, const RenderOptions& options)
    : StreamingRenderer(std::make_shared<const CoarticulationTables>(model), options) {}

StreamingRenderer::StreamingRenderer(std::shared_ptr<const CoarticulationTables> tables, const RenderOptions& options)
    : options_(options), scheduler_(tables->model(), schedule_options(options)), evaluator_(std::move(tables)) {
  window_.reserve(2 * kWindowRadius + 2);  // the most it holds (renderer.hpp)
}

void StreamingRenderer::push(const Segment& segment, Track& out) {
  if (finished_) throw std::logic_error("StreamingRenderer::push after finish");
  window_.push_back(segment);
  scheduler_.add_segment(segment, pushed_, scheduled_);
  ++pushed_;
  pending_.insert(pending_.end(), scheduled_.begin(), scheduled_.end());
  scheduled_.clear();
  emit_ready(out, false);
}

void StreamingRenderer::finish(Track& out) {
  if (finished_) return;
  scheduler_.finish(scheduled_);
  pending_.insert(pending_.end(), scheduled_.begin(), scheduled_.end());
  scheduled_.clear();
  finished_ = true;
  emit_ready(out, true);
}

void StreamingRenderer::emit_ready(Track& out, bool finishing) {
  const auto lookahead = static_cast<std::size_t>(options_.lookahead);
  std::size_t emitted = 0;  // frames at the front of pending_ appended to `out`
  while (emitted < pending_.size()) {
    const std::size_t segment = pending_[emitted].segment;
    if (!finishing && segment + lookahead >= pushed_) break;  // segment k+lookahead not known yet
    const auto run_begin = pending_.cbegin() + static_cast<std::ptrdiff_t>(emitted);
    const auto run_end = same_segment_end(run_begin, pending_.cend());
    const auto [first, last] = window_range(segment, pushed_, options_.lookahead);
    const auto window = std::span<const Segment>(window_).subspan(first - first_index_, last - first + 1);
    append_frames(out, run_begin, run_end, evaluator_, window, segment - first);
    emitted = static_cast<std::size_t>(run_end - pending_.cbegin());
  }
  pending_.erase(pending_.cbegin(), pending_.cbegin() + static_cast<std::ptrdiff_t>(emitted));
  // Keep only the segments a future frame can still see.
  const std::size_t oldest_needed = pending_.empty() ? pushed_ : pending_.front().segment;
  const std::size_t keep_from = oldest_needed >= kWindowRadius ? oldest_needed - kWindowRadius : 0;
  if (first_index_ < keep_from) {
    window_.erase(window_.begin(), window_.begin() + static_cast<std::ptrdiff_t>(keep_from - first_index_));
    first_index_ = keep_from;
  }
}

}  // namespace lipsync
