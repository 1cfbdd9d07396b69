// Frames to protobuf (wire.hpp). A batch's channel values are one copy (the
// track's frames are contiguous); ARKit weights are retargeted and viseme
// weights computed frame by frame, straight into the batch.
#include "wire.hpp"

#include <array>
#include <span>
#include <string>

#include "lipsync/release_delay.hpp"

namespace lipsync::server {
namespace {

v1::FrameKind to_proto(FrameKind kind) {
  switch (kind) {
    case FrameKind::uniform:
      return v1::FRAME_KIND_UNIFORM;
    case FrameKind::closure_start:
      return v1::FRAME_KIND_CLOSURE_START;
    case FrameKind::closure_end:
      return v1::FRAME_KIND_CLOSURE_END;
    case FrameKind::short_segment:
      return v1::FRAME_KIND_SHORT_SEGMENT;
  }
  return v1::FRAME_KIND_UNSPECIFIED;
}

}  // namespace

v1::TrackHeader encode_header(const Plan& plan, const v1::AnimationSettings& settings, bool with_session) {
  v1::TrackHeader header;
  header.set_model(plan.model->name);
  header.set_fps(static_cast<std::uint32_t>(plan.engine.render.fps));
  if (plan.channels) {
    for (const auto& channel : plan.model->model->channels()) header.add_channels(channel.name);
  }
  if (plan.arkit) {
    for (const auto name : kArkitNames) header.add_arkit_names(std::string(name));
  }
  if (with_session) header.set_session(settings.session());
  if (settings.has_media_clock()) *header.mutable_media_clock() = settings.media_clock();
  header.set_lookahead(static_cast<std::uint32_t>(plan.engine.render.lookahead));
  // What a stream at this lookahead waits (Render says it too, so that its header equals Animate's).
  header.set_release_delay_us(read_speech_release_delay_us(plan.engine.render.lookahead));
  if (plan.visemes) {
    header.set_viseme_vocabulary(plan.viseme_vocabulary);
    for (const auto& name : plan.visemes->names()) header.add_viseme_names(name);
  }
  return header;
}

void encode_frames(const Plan& plan, const Track& track, std::size_t begin, std::size_t end, std::uint64_t first_frame,
                   v1::FrameBatch& batch, StreamEncoder& stream) {
  const std::size_t count = end - begin;
  const std::size_t channels = track.channel_count;
  batch.set_first_frame(first_frame);
  batch.mutable_t_us()->Reserve(static_cast<int>(count));
  batch.mutable_kinds()->Reserve(static_cast<int>(count));
  if (plan.channels) batch.mutable_values()->Reserve(static_cast<int>(count * channels));
  if (plan.arkit) batch.mutable_arkit()->Reserve(static_cast<int>(count * kArkitNames.size()));
  batch.mutable_t_us()->Add(track.t_us.begin() + static_cast<std::ptrdiff_t>(begin),
                            track.t_us.begin() + static_cast<std::ptrdiff_t>(end));
  for (std::size_t frame = begin; frame < end; ++frame) batch.add_kinds(to_proto(track.kinds[frame]));
  if (plan.channels) {
    // Frames are contiguous in the track: one copy for the whole batch.
    const float* first = track.values.data() + begin * channels;
    batch.mutable_values()->Add(first, first + count * channels);
  }
  if (plan.arkit) {
    std::array<float, kArkitNames.size()> arkit{};
    for (std::size_t frame = begin; frame < end; ++frame) {
      plan.model->model->retarget_to_arkit(track.frame_values(frame), arkit);
      batch.mutable_arkit()->Add(arkit.begin(), arkit.end());
    }
  }
  if (plan.visemes) {
    const std::size_t visemes = plan.visemes->viseme_count();
    auto& weights = *batch.mutable_viseme_weights();
    weights.Resize(static_cast<int>(count * visemes), 0.0f);
    for (std::size_t frame = begin; frame < end; ++frame) {
      const std::span<float> frame_weights(weights.mutable_data() + (frame - begin) * visemes, visemes);
      plan.visemes->weigh(track.frame_values(frame), frame_weights);
      const std::uint32_t winner = plan.visemes->winner(frame_weights, track.frame_articulation(frame));
      if (const auto event = stream.viseme_detector.next(track.t_us[frame], winner)) {
        v1::VisemeEvent* wire_event = batch.add_viseme_events();
        wire_event->set_viseme(event->viseme);
        wire_event->set_start_us(event->start_us);
      }
    }
  }
  if (stream.face) stream.face->encode(track, begin, end, batch);
}

void encode_summary(std::uint64_t frames, std::uint64_t phonemes, std::int64_t duration_us, v1::TrackSummary& summary) {
  summary.set_frames(frames);
  summary.set_phonemes(phonemes);
  summary.set_duration_us(duration_us);
}

}  // namespace lipsync::server
