// The live stream's renderer (lipsync/live_renderer.hpp).
#include "lipsync/live_renderer.hpp"

#include <algorithm>

#include "lipsync/error.hpp"

namespace lipsync {

LiveRenderer::LiveRenderer(std::shared_ptr<const CoarticulationTables> tables, const ArticulationModel& model,
                           const PhoneSet& phone_set, std::string source, SegmentOptions segment_options,
                           const RenderOptions& options)
    : builder_(model, phone_set, std::move(source), segment_options),
      renderer_(std::move(tables), options),
      guess_builder_(builder_),
      guess_renderer_(renderer_) {
  released_.channel_count = model.channel_count();
  released_.fps = options.fps;
}

void LiveRenderer::push_final(const LabeledInterval& phoneme, Track& out) {
  segments_.clear();
  builder_.push(phoneme, segments_);
  ++final_count_;
  released_.clear();
  for (const Segment& segment : segments_) renderer_.push(segment, released_);
  take_frames(released_, INT64_MAX, out);
}

void LiveRenderer::emit_until(std::int64_t until_us, std::span<const LabeledInterval> guess, Track& out) {
  if (until_us <= emitted_until_us_) return;
  // Assigned, not constructed: their vectors keep their room, so a deadline allocates nothing once
  // the stream has warmed up (a stream of hours would otherwise fragment the heap).
  guess_builder_ = builder_;
  guess_renderer_ = renderer_;
  released_.clear();
  for (const LabeledInterval& phoneme : guess) {
    segments_.clear();
    try {
      guess_builder_.push(phoneme, segments_);
    } catch (const InputError&) {
      break;  // a guess the phone set cannot take ends the guess
    }
    for (const Segment& segment : segments_) guess_renderer_.push(segment, released_);
  }
  guess_renderer_.finish(released_);
  take_frames(released_, until_us, out);
}

void LiveRenderer::finish(Track& out) {
  released_.clear();
  renderer_.finish(released_);
  take_frames(released_, INT64_MAX, out);
}

void LiveRenderer::take_frames(const Track& from, std::int64_t until_us, Track& out) {
  const auto first = std::upper_bound(from.t_us.begin(), from.t_us.end(), emitted_until_us_) - from.t_us.begin();
  const auto last = std::upper_bound(from.t_us.begin(), from.t_us.end(), until_us) - from.t_us.begin();
  if (first >= last) return;
  const std::size_t channels = from.channel_count;
  out.t_us.insert(out.t_us.end(), from.t_us.begin() + first, from.t_us.begin() + last);
  out.kinds.insert(out.kinds.end(), from.kinds.begin() + first, from.kinds.begin() + last);
  out.values.insert(out.values.end(), from.values.begin() + first * static_cast<std::ptrdiff_t>(channels),
                    from.values.begin() + last * static_cast<std::ptrdiff_t>(channels));
  if (!from.articulation.empty()) {
    out.articulation.insert(out.articulation.end(), from.articulation.begin() + first,
                            from.articulation.begin() + last);
  }
  emitted_until_us_ = out.t_us.back();
}

}  // namespace lipsync
