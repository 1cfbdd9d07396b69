// Render: a whole utterance in one unary call. The phonemes go through the same
// PhonemeInput as Animate's, the track comes from render_track and is encoded as
// one FrameBatch by the same wire encoding, so with lookahead 7 the response
// equals the stream's frames bit for bit. A Render with the mesh output costs
// seconds of solver work for a long utterance: it runs whole on a face thread
// (face_workers.hpp), off gRPC's reactions; without the mesh it runs in the method.
#include <memory>
#include <vector>

#include "lipsync/renderer.hpp"
#include "phoneme_input.hpp"
#include "plan.hpp"
#include "service.hpp"
#include "unary_call.hpp"
#include "wire.hpp"

namespace lipsync::server {
namespace {

grpc::Status render(LipSyncService& service, const v1::RenderRequest& request, v1::RenderResponse& response) {
  const ServerConfig& config = service.config();
  Plan plan;
  if (auto status = resolve_settings(request.settings(), service.catalog(), false, plan); !status.ok()) {
    return status;
  }
  if (static_cast<std::size_t>(request.phonemes_size()) > config.max_phonemes) {
    return too_many_phonemes(config.max_phonemes);
  }
  PhonemeInput input(plan, config);
  std::vector<Segment> segments;
  for (const v1::Phoneme& phoneme : request.phonemes()) {
    if (auto status = input.push(phoneme, segments); !status.ok()) return status;
  }
  FaceSetup face_setup;
  if (auto status = prepare_face(plan, service.faces(), face_setup); !status.ok()) return status;
  std::unique_ptr<FaceStream> face_stream;
  if (plan.mesh) {
    face_stream = std::make_unique<FaceStream>(
        *face_setup.topology, service.faces().solver(*face_setup.topology, *face_setup.rig), plan.mesh_encoding);
  }
  StreamEncoder encoder{.face = face_stream.get(), .viseme_detector = {}};
  const Track track = render_track(plan.model->tables, segments, plan.engine.render);
  *response.mutable_header() = plan.header;
  const auto encoding = Clock::now();
  encode_frames(plan, track, 0, track.frame_count(), 0, *response.mutable_frames(), encoder);
  if (face_stream) service.metrics().face_solver.observe_us(microseconds_since(encoding));
  service.metrics().phonemes_received.add(static_cast<std::uint64_t>(request.phonemes_size()));
  service.metrics().frames_sent.with({"Render"}).add(track.frame_count());
  service.metrics().messages_sent.with({"Render"}).add();
  encode_summary(track.frame_count(), static_cast<std::uint64_t>(request.phonemes_size()), input.end_us(),
                 *response.mutable_summary());
  return grpc::Status::OK;
}

}  // namespace

grpc::ServerUnaryReactor* LipSyncService::Render(grpc::CallbackServerContext* context,
                                                 const v1::RenderRequest* request, v1::RenderResponse* response) {
  if (grpc::Status admission = admission_.admit_render(context->peer()); !admission.ok()) {
    return unary(context, "Render", [&] { return admission; }, &metrics_);
  }
  // Counted out when the call is done (the response has left), not at Finish: a drain
  // must not take a Render whose response is still on its way for a finished one.
  auto* call = new UnaryCall(
      "Render", *context, [this](const grpc::Status&) { admission_.release_render(); }, &metrics_);
  if (!wants_mesh(request->settings())) {
    call->run([&] { return render(*this, *request, *response); });
    return call;
  }
  // Seconds of solver work for a long utterance: off the reaction (face_workers.hpp).
  face_workers_.post([this, call, request, response] { call->run([&] { return render(*this, *request, *response); }); });
  return call;
}

}  // namespace lipsync::server
