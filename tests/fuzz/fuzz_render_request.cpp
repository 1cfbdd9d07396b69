// libFuzzer target: the server's request validation, in process, without
// sockets. The bytes are a lipsync.v1.RenderRequest on the wire (settings and
// phonemes, as Render and the settings + chunks of Animate carry them); they go
// through what both calls run: resolve_settings, PhonemeInput (SegmentBuilder
// under the limits), render_track and the FrameBatch encoding.
// Contract: every refusal is a non-OK status with a message (never a throw);
// an accepted request gives contiguous segments and frames whose times
// strictly increase, with values for every frame and output.
// The mesh output is switched off: the face solver would cost seconds per run
// (the rig it loads is fuzzed by fuzz_face_rig_from_json).
#include <google/protobuf/stubs/logging.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "catalog.hpp"
#include "fuzz_support.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/server/config.hpp"
#include "lipsync/v1/lipsync.pb.h"
#include "rpc/phoneme_input.hpp"
#include "rpc/plan.hpp"
#include "rpc/wire.hpp"

namespace {

/// The server's limits, with a 60 s utterance so that each run stays fast.
lipsync::server::ServerConfig fuzz_config() {
  lipsync::server::ServerConfig config;
  config.max_utterance_ms = 60'000;
  return config;
}

void check_refusal(const grpc::Status& status) {
  lipsync::fuzz::check(status.error_code() == grpc::StatusCode::INVALID_ARGUMENT ||
                           status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED,
                       "a refusal is INVALID_ARGUMENT or RESOURCE_EXHAUSTED");
  lipsync::fuzz::check(!status.error_message().empty(), "a refusal says why");
}

}  // namespace

/// Protobuf's log of undecodable UTF-8 strings would drown the fuzzer's own output.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lipsync;
  using namespace lipsync::server;
  static const ModelCatalog catalog({});
  static const ServerConfig config = fuzz_config();

  v1::RenderRequest request;
  if (!request.ParseFromArray(data, static_cast<int>(size))) return 0;  // gRPC refuses it before us
  request.mutable_settings()->mutable_outputs()->mutable_mesh()->set_enabled(false);

  for (const bool with_session : {false, true}) {
    Plan plan;
    if (grpc::Status status = resolve_settings(request.settings(), catalog, with_session, plan); !status.ok()) {
      check_refusal(status);
      continue;
    }
    fuzz::check(plan.model != nullptr && plan.phone_set != nullptr, "a plan has a model and a phone set");
    PhonemeInput input(plan, config);
    std::vector<Segment> segments;
    grpc::Status status = grpc::Status::OK;
    for (const v1::Phoneme& phoneme : request.phonemes()) {
      status = input.push(phoneme, segments);
      if (!status.ok()) break;
    }
    if (!status.ok()) {
      check_refusal(status);
      continue;
    }
    fuzz::check_segments(segments, *plan.model->model);
    fuzz::check(segments.empty() || segments.back().end_us == input.end_us(), "segments end at the input's end");
    if (segments.empty()) continue;
    const Track track = render_track(plan.model->tables, segments, plan.engine.render);
    for (std::size_t i = 1; i < track.frame_count(); ++i) {
      fuzz::check(track.t_us[i] > track.t_us[i - 1], "frame times strictly increase");
    }
    fuzz::check(track.values.size() == track.frame_count() * track.channel_count, "values for every frame");
    v1::FrameBatch batch;
    StreamEncoder encoder;  // no face (the mesh output is off here); the viseme events when asked for
    encode_frames(plan, track, 0, track.frame_count(), 0, batch, encoder);
  }
  return 0;
}
