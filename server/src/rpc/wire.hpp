// Wire encoding: the engine's results as lipsync.v1 messages. A plan's track
// header, frames [begin, end) of a Track as one FrameBatch (channels, ARKit
// weights retargeted by the model, viseme weights and events, mesh positions
// from the stream's face) and
// the summary that ends a track. Animate, Subscribe (through the session) and
// Render send exactly these, which is what keeps them equal bit for bit.
#pragma once

#include <cstddef>
#include <cstdint>

#include "face/face_stream.hpp"
#include "lipsync/track.hpp"
#include "lipsync/v1/lipsync.pb.h"
#include "lipsync/visemes.hpp"
#include "rpc/plan.hpp"

namespace lipsync::server {

/// The track header for `plan` (the mesh topology is added by prepare_face).
v1::TrackHeader encode_header(const Plan& plan, const v1::AnimationSettings& settings, bool with_session);

/// What a stream carries from one batch to the next besides the frame count:
/// its face (mesh output only) and its viseme event detector, so that a stream
/// cut into batches gives the events of a whole track.
struct StreamEncoder {
  FaceStream* face = nullptr;
  VisemeEventDetector viseme_detector;
};

/// Frames [begin, end) of `track` into `batch`, numbered from `first_frame`;
/// the stream's face (if any) steps through them and adds their positions, and
/// with the viseme output their weights and the events starting at them are added.
void encode_frames(const Plan& plan, const Track& track, std::size_t begin, std::size_t end, std::uint64_t first_frame,
                   v1::FrameBatch& batch, StreamEncoder& stream);

/// The summary after the last frame.
void encode_summary(std::uint64_t frames, std::uint64_t phonemes, std::int64_t duration_us, v1::TrackSummary& summary);

}  // namespace lipsync::server
