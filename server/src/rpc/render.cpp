// Render: a whole utterance in one unary call. The phonemes go through the same
// PhonemeInput as Animate's, the track comes from render_track and is encoded as
// one FrameBatch by the same wire encoding, so with lookahead 7 the response
// equals the stream's frames bit for bit. A Render with the mesh output costs
// seconds of solver work for a long utterance: it runs whole on a face thread
// (face_workers.hpp), off gRPC's reactions; without the mesh it runs in the method.
#include <memory>
#include <vector>

#include "lipsync/renderer.hpp"
#include "rpc/phoneme_input.hpp"
#include "rpc/plan.hpp"
#include "rpc/service.hpp"
#include "rpc/unary_call.hpp"
#include "rpc/wire.hpp"

namespace lipsync::server {
namespace {

/// The track of `request`, whose settings are already resolved into `plan`.
grpc::Status render(LipSyncService& service, Plan& plan, const v1::RenderRequest& request,
                    v1::RenderResponse& response) {
  const ServerConfig& config = service.config();
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
        *face_setup.topology, service.faces().solver(*face_setup.topology, *face_setup.rig, plan.mesh_solve),
        plan.mesh_encoding, plan.blinks);
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

grpc::ServerUnaryReactor* LipSyncService::Render(grpc::CallbackServerContext* context, const v1::RenderRequest* request,
                                                 v1::RenderResponse* response) {
  handoff_acquire(this);  // the service as built before the server started (tsan_handoff.hpp)
  if (grpc::Status admission = admission_.admit_render(context->peer()); !admission.ok()) {
    return unary(*this, context, "Render", [&] { return admission; });
  }
  // What the call holds until it is done: until its response has left, not until Finish
  // (a drain must not take a Render whose response is still on its way for a finished one).
  struct Holds {
    QuotaHold mesh_quota;
    std::int64_t face_weight = 0;  // once admitted against the face's capacity
  };
  auto holds = std::make_shared<Holds>();
  auto* call = new UnaryCall(*this, "Render", *context, [this, holds](const grpc::Status&) {
    if (holds->face_weight > 0) face_capacity_.release(holds->face_weight);
    admission_.release_render();
  });
  // The tenant (tenants.hpp): its key, its phoneme rate and, with the mesh, its mesh calls.
  Caller caller;
  grpc::Status refused = tenants_.authenticate(*context, "Render", caller);
  if (refused.ok()) call->set_tenant(caller.tenant());
  if (refused.ok()) refused = caller.take_phonemes(static_cast<std::size_t>(request->phonemes_size()));
  if (refused.ok() && wants_mesh(request->settings())) refused = caller.hold(Quota::mesh_streams, holds->mesh_quota);
  if (!refused.ok()) {
    call->run([&] { return refused; });
    return call;
  }
  // Settings first: a bad field is INVALID_ARGUMENT naming it, whatever the face's load.
  auto plan = std::make_shared<Plan>();
  if (grpc::Status invalid_settings = resolve_settings(request->settings(), catalog(), false, *plan);
      !invalid_settings.ok()) {
    call->run([&] { return invalid_settings; });
    return call;
  }
  if (!plan->mesh) {
    call->run([&] { return render(*this, *plan, *request, *response); });
    return call;
  }
  // Seconds of solver work for a long utterance: off the reaction (face_workers.hpp),
  // admitted against the face's capacity (face_capacity.hpp) for as long as it runs.
  const std::int64_t weight =
      FaceCapacity::weight_milli(plan->engine.mesh_subdivision, plan->engine.render.fps, plan->mesh_solve);
  if (grpc::Status capacity = face_capacity_.admit(weight); !capacity.ok()) {
    call->run([&] { return capacity; });
    return call;
  }
  holds->face_weight = weight;
  face_workers_.post(
      [this, call, plan, request, response] { call->run([&] { return render(*this, *plan, *request, *response); }); });
  return call;
}

}  // namespace lipsync::server
