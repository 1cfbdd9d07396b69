// The LipSync service: requests become engine calls, frames become messages.
//
// Every call resolves its AnimationSettings once (model, phone set, fps,
// lookahead, closure fraction, outputs) into a Plan and rejects bad values with
// INVALID_ARGUMENT naming the field. Phonemes go one at a time through a
// SegmentBuilder (source "phoneme stream", line = 1-based phoneme index), so a
// bad phoneme is reported with its index whatever the chunking. Animate feeds
// the segments to a StreamingRenderer and sends, after each chunk, every frame
// the renderer released as FrameBatch messages; Render uses render_track. With
// lookahead 7 the two are equal bit for bit.
//
// Reactions never block: the engine costs about a microsecond per frame, so
// frames are computed in OnReadDone, and writes go through an Outbox (one write
// in flight, Finish only when none is). A producer that reads its frames slower
// than it sends phonemes is held back: while thousands of its frames wait, its
// stream reads no more phonemes, and HTTP/2 flow control stops the client.
//
// The mesh output (face_stream.hpp) is the exception to "cheap": a FaceSolver
// costs about a millisecond per frame and tens of ms to build (streams take
// built ones from a pool when they can). A stream that asks
// for it gets a FaceLane (face_workers.hpp): its solver is built, its frames
// are encoded and everything it sends after its header (frames, summary,
// Finish) leaves from low-priority face threads, in order; the reactions only
// queue the released frames. A Render with the mesh runs there whole. Streams
// that do not ask for the mesh never create or touch a solver or a lane.
#include "service.hpp"

#include <array>
#include <chrono>
#include <cmath>
#include <mutex>
#include <optional>
#include <thread>

#include <grpcpp/alarm.h>
#include <spdlog/spdlog.h>

#include "lipsync/error.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"

namespace lipsync::server {
namespace {

constexpr std::size_t kMaxFramesPerBatch = 512;
// Backpressure on a producer that reads its frames slower than it sends
// phonemes: with more than kReadPauseFrames frames waiting for it (queued for
// writing, or for its face), the stream stops reading phonemes, so HTTP/2 flow
// control holds the client back; it reads again once at most kReadResumeFrames wait.
constexpr std::size_t kReadPauseFrames = 4096;
constexpr std::size_t kReadResumeFrames = 1024;
constexpr const char* kStreamSource = "phoneme stream";

using Clock = std::chrono::steady_clock;

struct Plan {
  const ModelEntry* model = nullptr;
  const PhoneSet* phone_set = nullptr;
  RenderOptions render;
  SegmentOptions segment;
  bool channels = true;
  bool arkit = true;
  bool mesh = false;
  int mesh_subdivision = 1;
  v1::MeshEncoding mesh_encoding = v1::MESH_ENCODING_FLOAT32;
  v1::TrackHeader header;
};

grpc::Status invalid(const std::string& message) {
  return {grpc::StatusCode::INVALID_ARGUMENT, message};
}

bool wants_mesh(const v1::AnimationSettings& settings) {
  return settings.outputs().has_mesh() && settings.outputs().mesh().enabled();
}

grpc::Status resolve_settings(const v1::AnimationSettings& settings, const ModelCatalog& catalog,
                              bool with_session, Plan& plan) {
  plan.model = catalog.find(settings.model());
  if (!plan.model) {
    return invalid("settings.model: unknown model '" + settings.model() + "' (known: " + catalog.names() + ")");
  }
  const std::string phone_set = settings.phone_set().empty() ? "arpabet" : settings.phone_set();
  plan.phone_set = plan.model->find_phone_set(phone_set);
  if (!plan.phone_set) {
    std::string known;
    for (const auto& set : plan.model->phone_sets) known += (known.empty() ? "" : ", ") + set.name();
    return invalid("settings.phone_set: unknown phone set '" + phone_set + "' for model '" + plan.model->name +
                   "' (known: " + known + ")");
  }
  const std::uint32_t fps = settings.fps() == 0 ? 30 : settings.fps();
  if (fps > 240) return invalid("settings.fps: " + std::to_string(fps) + " is out of range 1..240 (0 means 30)");
  const std::uint32_t lookahead = settings.has_lookahead() ? settings.lookahead() : 7;
  if (lookahead > 7) return invalid("settings.lookahead: " + std::to_string(lookahead) + " is out of range 0..7");
  const double closure = settings.closure_fraction() == 0.0 ? 0.6 : settings.closure_fraction();
  if (!(closure > 0.0 && closure < 1.0)) {
    return invalid("settings.closure_fraction: " + std::to_string(settings.closure_fraction()) +
                   " is outside (0, 1) (0 means 0.6)");
  }
  if (with_session && settings.session().size() > 256) {
    return invalid("settings.session: the name is longer than 256 bytes");
  }
  plan.render = {.fps = static_cast<int>(fps), .fixed_rate = settings.fixed_rate(),
                 .lookahead = static_cast<int>(lookahead)};
  plan.segment.closure_fraction = closure;
  const bool any = settings.outputs().channels() || settings.outputs().arkit();
  plan.channels = !any || settings.outputs().channels();
  plan.arkit = !any || settings.outputs().arkit();
  if (wants_mesh(settings)) {
    const v1::MeshOutput& mesh = settings.outputs().mesh();
    plan.mesh = true;
    if (mesh.has_subdivision()) {
      if (mesh.subdivision() > static_cast<std::uint32_t>(FaceLibrary::kMaxSubdivision)) {
        return invalid("settings.outputs.mesh.subdivision: " + std::to_string(mesh.subdivision()) +
                       " is out of range 0..2 (unset means 1)");
      }
      plan.mesh_subdivision = static_cast<int>(mesh.subdivision());
    }
    switch (mesh.encoding()) {
      case v1::MESH_ENCODING_UNSPECIFIED:
      case v1::MESH_ENCODING_FLOAT32: plan.mesh_encoding = v1::MESH_ENCODING_FLOAT32; break;
      case v1::MESH_ENCODING_INT16: plan.mesh_encoding = v1::MESH_ENCODING_INT16; break;
      default:
        return invalid("settings.outputs.mesh.encoding: unknown encoding " + std::to_string(mesh.encoding()) +
                       " (FLOAT32 or INT16)");
    }
  }

  plan.header.set_model(plan.model->name);
  plan.header.set_fps(fps);
  if (plan.channels) {
    for (const auto& channel : plan.model->model->channels()) plan.header.add_channels(channel.name);
  }
  if (plan.arkit) {
    for (const auto name : kArkitNames) plan.header.add_arkit_names(std::string(name));
  }
  if (with_session) plan.header.set_session(settings.session());
  if (settings.has_media_clock()) *plan.header.mutable_media_clock() = settings.media_clock();
  plan.header.set_lookahead(lookahead);
  return grpc::Status::OK;
}

v1::FrameKind to_proto(FrameKind kind) {
  switch (kind) {
    case FrameKind::uniform: return v1::FRAME_KIND_UNIFORM;
    case FrameKind::closure_start: return v1::FRAME_KIND_CLOSURE_START;
    case FrameKind::closure_end: return v1::FRAME_KIND_CLOSURE_END;
    case FrameKind::short_segment: return v1::FRAME_KIND_SHORT_SEGMENT;
  }
  return v1::FRAME_KIND_UNSPECIFIED;
}

/// What a stream's face needs (its solver is built later, off the reaction:
/// see FaceWorkers), with the topology put in the plan's header.
struct FaceSetup {
  const FaceTopology* topology = nullptr;
  const face::FaceRig* rig = nullptr;
  std::size_t frames_per_batch = kMaxFramesPerBatch;
};

/// The face of a plan that asks for the mesh (nothing otherwise). INVALID_ARGUMENT
/// if the model cannot drive it.
grpc::Status prepare_face(Plan& plan, FaceLibrary& faces, FaceSetup& setup) {
  if (!plan.mesh) return grpc::Status::OK;
  try {
    setup.rig = &faces.rig(*plan.model->model);
  } catch (const InputError& error) {
    return invalid("settings.outputs.mesh: model '" + plan.model->name + "' cannot drive the face: " + error.what());
  }
  setup.topology = &faces.topology(plan.mesh_subdivision);
  // One frame per message: a frame of positions is 5–115 kB already, and a
  // batch would hold each frame back until the solver has done the ones after it.
  setup.frames_per_batch = 1;
  *plan.header.mutable_mesh() = header_topology(*setup.topology, plan.mesh_encoding);
  return grpc::Status::OK;
}

/// Frames [begin, end) of `track` into `batch`, numbered from `first_frame`;
/// `face_stream` (if any) steps through them and adds their positions.
void encode_frames(const Plan& plan, const Track& track, std::size_t begin, std::size_t end,
                   std::uint64_t first_frame, v1::FrameBatch& batch, FaceStream* face_stream) {
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
  if (face_stream) face_stream->encode(track, begin, end, batch);
}

LabeledInterval to_interval(const v1::Phoneme& phoneme, int index) {
  return {phoneme.label(), phoneme.start_us(), phoneme.end_us(), index};
}

std::string status_name(const grpc::Status& status) {
  static constexpr std::array<const char*, 17> kNames = {
      "OK", "CANCELLED", "UNKNOWN", "INVALID_ARGUMENT", "DEADLINE_EXCEEDED", "NOT_FOUND",
      "ALREADY_EXISTS", "PERMISSION_DENIED", "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION", "ABORTED",
      "OUT_OF_RANGE", "UNIMPLEMENTED", "INTERNAL", "UNAVAILABLE", "DATA_LOSS", "UNAUTHENTICATED"};
  const auto code = static_cast<std::size_t>(status.error_code());
  std::string name = code < kNames.size() ? kNames[code] : std::to_string(code);
  if (!status.ok()) name += " (" + status.error_message() + ")";
  return name;
}

double elapsed_ms(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
}

grpc::Status too_many_phonemes(std::size_t limit) {
  return {grpc::StatusCode::RESOURCE_EXHAUSTED,
          "the utterance has more than " + std::to_string(limit) + " phonemes (--max-phonemes=" +
              std::to_string(limit) + ")"};
}

grpc::Status too_long(int index, std::int64_t end_us, std::int64_t limit_ms) {
  return {grpc::StatusCode::RESOURCE_EXHAUSTED,
          std::string(kStreamSource) + ":" + std::to_string(index) + ": the utterance reaches " +
              std::to_string(end_us) + " us, longer than --max-utterance-ms=" + std::to_string(limit_ms)};
}

// ---------------------------------------------------------------------------
// Animate: one bidirectional stream per utterance.

class AnimateReactor final : public grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage>,
                             public OutboxTarget {
 public:
  AnimateReactor(LipSyncService& service, grpc::CallbackServerContext* context)
      : service_(service), context_(context), outbox_(*this), started_(Clock::now()) {
    const grpc::Status admission = service_.admit_stream();
    if (!admission.ok()) {
      outbox_.close(admission);
      return;
    }
    admitted_ = true;
    spdlog::info("Animate start peer={}", context_->peer());
    StartRead(&request_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {
      if (phase_ == Phase::ended) {
        in_order([this] { outbox_.close(grpc::Status::OK); });
      } else {
        fail(invalid("the client closed the stream before `end` (after " + std::to_string(phonemes_) +
                     " phonemes)"),
             "producer disconnected before the end of the utterance");
      }
      return;
    }
    grpc::Status status;
    try {
      status = handle(request_);
    } catch (const std::exception& error) {
      status = grpc::Status(grpc::StatusCode::INTERNAL, error.what());
    }
    if (!status.ok()) {
      fail(status, "producer failed: " + status.error_message());
      return;
    }
    std::lock_guard lock(flow_mutex_);
    if (frames_waiting() > kReadPauseFrames) {
      read_paused_ = true;  // a write is in flight or a face job queued: its completion resumes
      return;
    }
    StartRead(&request_);
  }

  void OnWriteDone(bool ok) override {
    outbox_.on_write_done(ok);
    std::lock_guard lock(flow_mutex_);
    if (read_paused_ && frames_waiting() <= kReadResumeFrames) {
      read_paused_ = false;
      StartRead(&request_);
    }
  }

  void OnCancel() override {
    stopped_ = true;
    outbox_.abort(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
    fail_session("producer disconnected: the stream was cancelled");
  }

  void OnDone() override {
    const auto status = outbox_.final_status().value_or(grpc::Status::OK);
    if (admitted_) {
      spdlog::info("Animate end peer={} session='{}' phonemes={} frames={} duration_ms={:.1f} status={}",
                   context_->peer(), session_name_, phonemes_, frames_sent_, elapsed_ms(started_),
                   status_name(status));
      service_.release_stream();
    } else {
      spdlog::warn("Animate refused peer={} status={}", context_->peer(), status_name(status));
    }
    stopped_ = true;
    if (lane_) {
      lane_->retire([this] { delete this; });  // a face job may still be running
    } else {
      delete this;
    }
  }

  void start_write(const v1::TrackMessage* message) override { StartWrite(message); }
  void finish(const grpc::Status& status) override { Finish(status); }

 private:
  enum class Phase { awaiting_settings, streaming, ended };

  grpc::Status handle(const v1::AnimateRequest& request) {
    switch (phase_) {
      case Phase::awaiting_settings:
        if (!request.has_settings()) return invalid("first message must be settings");
        return start(request.settings());
      case Phase::streaming:
        if (request.has_phonemes()) return add_phonemes(request.phonemes());
        if (request.has_end()) return end();
        if (request.has_settings()) return invalid("settings sent twice: only the first message may be settings");
        return invalid("empty AnimateRequest after " + std::to_string(phonemes_) + " phonemes");
      case Phase::ended:
        if (request.has_phonemes() && request.phonemes().phonemes_size() > 0) {
          const auto& phoneme = request.phonemes().phonemes(0);
          return invalid(std::string(kStreamSource) + ":" + std::to_string(phonemes_ + 1) + ": phoneme '" +
                         phoneme.label() + "': received after `end`");
        }
        return invalid("message received after `end` (the utterance had " + std::to_string(phonemes_) +
                       " phonemes)");
    }
    return grpc::Status::OK;
  }

  grpc::Status start(const v1::AnimationSettings& settings) {
    if (auto status = resolve_settings(settings, service_.catalog(), true, plan_); !status.ok()) return status;
    if (auto status = prepare_face(plan_, service_.faces(), face_setup_); !status.ok()) return status;
    auto header = std::make_shared<v1::TrackMessage>();
    *header->mutable_header() = plan_.header;
    if (!settings.session().empty()) {
      std::shared_ptr<Session> session;
      if (auto status = service_.sessions().open(settings.session(), header, session); !status.ok()) {
        return status;
      }
      std::lock_guard lock(session_mutex_);
      session_ = std::move(session);
      session_name_ = settings.session();
    }
    const ArticulationModel& model = *plan_.model->model;
    builder_.emplace(model, *plan_.phone_set, kStreamSource, plan_.segment);
    renderer_.emplace(plan_.model->tables, plan_.render);
    track_.channel_count = model.channel_count();
    track_.fps = plan_.render.fps;
    outbox_.push(header);
    if (plan_.mesh) {
      // From here on everything that leaves this stream goes through the lane, in order.
      lane_.emplace(service_.face_workers());
      lane_->post([this, encoding = plan_.mesh_encoding] {
        if (!stopped_) {
          face_ = std::make_unique<FaceStream>(*face_setup_.topology,
                                               service_.faces().solver(*face_setup_.topology, *face_setup_.rig),
                                               encoding);
        }
      });
    }
    phase_ = Phase::streaming;
    return grpc::Status::OK;
  }

  grpc::Status add_phonemes(const v1::PhonemeChunk& chunk) {
    const ServerConfig& config = service_.config();
    for (const v1::Phoneme& phoneme : chunk.phonemes()) {
      if (phonemes_ >= config.max_phonemes) return too_many_phonemes(config.max_phonemes);
      const int index = static_cast<int>(++phonemes_);
      try {
        builder_->push(to_interval(phoneme, index), segments_);
      } catch (const InputError& error) {
        return invalid(error.what());
      }
      if (builder_->end_us() > config.max_utterance_ms * 1000) {
        return too_long(index, builder_->end_us(), config.max_utterance_ms);
      }
      for (const Segment& segment : segments_) renderer_->push(segment, track_);
      segments_.clear();
    }
    send_frames();
    return grpc::Status::OK;
  }

  grpc::Status end() {
    renderer_->finish(track_);
    send_frames();
    in_order([this, phonemes = phonemes_, duration_us = builder_->end_us()] {
      auto summary = std::make_shared<v1::TrackMessage>();
      summary->mutable_summary()->set_frames(frames_sent_);
      summary->mutable_summary()->set_phonemes(phonemes);
      summary->mutable_summary()->set_duration_us(duration_us);
      if (auto session = current_session()) session->finish(summary);
      outbox_.push(summary);
    });
    phase_ = Phase::ended;
    return grpc::Status::OK;
  }

  /// Sends the frames the renderer released since the last call.
  void send_frames() {
    if (track_.frame_count() == 0) return;
    if (!lane_) {
      publish(track_);
      track_.clear();
      return;
    }
    auto released = std::make_shared<Track>();
    released->channel_count = track_.channel_count;
    released->fps = track_.fps;
    std::swap(*released, track_);
    frames_in_lane_ += released->frame_count();
    lane_->post([this, released] {
      // Counted out before they reach the outbox, so the write completion that
      // follows sees them only there (and can resume reading).
      frames_in_lane_ -= released->frame_count();
      if (!stopped_) publish(*released);
    });
  }

  std::size_t frames_waiting() const { return outbox_.queued_frames() + frames_in_lane_.load(); }

  void publish(const Track& track) {
    const std::size_t per_batch = face_setup_.frames_per_batch;
    for (std::size_t begin = 0; begin < track.frame_count(); begin += per_batch) {
      const std::size_t end = std::min(track.frame_count(), begin + per_batch);
      auto message = std::make_shared<v1::TrackMessage>();
      encode_frames(plan_, track, begin, end, frames_sent_, *message->mutable_frames(), face_.get());
      frames_sent_ += end - begin;
      // The session first: once the producer has seen a batch, subscribers can see it too.
      if (auto session = current_session()) session->publish(message, end - begin);
      outbox_.push(message, end - begin);
    }
  }

  /// Runs `step` now, or, for a mesh stream, after the face work queued before it.
  void in_order(std::function<void()> step) {
    if (!lane_) {
      step();
      return;
    }
    lane_->post([this, step = std::move(step)] {
      if (!stopped_) step();
    });
  }

  void fail(const grpc::Status& status, const std::string& reason) {
    stopped_ = true;
    outbox_.close(status);
    fail_session(reason);
  }

  void fail_session(const std::string& reason) {
    if (auto session = current_session()) session->fail(reason);
  }

  std::shared_ptr<Session> current_session() {
    std::lock_guard lock(session_mutex_);
    return session_;
  }

  LipSyncService& service_;
  grpc::CallbackServerContext* context_;
  Outbox outbox_;
  const Clock::time_point started_;
  bool admitted_ = false;
  Phase phase_ = Phase::awaiting_settings;
  v1::AnimateRequest request_;
  Plan plan_;
  std::optional<SegmentBuilder> builder_;
  std::optional<StreamingRenderer> renderer_;
  // Only when the mesh is asked for: the face is built and stepped on the lane.
  FaceSetup face_setup_;
  std::optional<FaceLane> lane_;
  std::unique_ptr<FaceStream> face_;
  std::atomic<bool> stopped_ = false;  // failed, cancelled or done: queued face work is skipped
  std::vector<Segment> segments_;
  Track track_;
  std::size_t phonemes_ = 0;
  std::atomic<std::uint64_t> frames_sent_ = 0;
  std::atomic<std::size_t> frames_in_lane_ = 0;
  std::mutex flow_mutex_;    // orders the read-pause decision against write completions
  bool read_paused_ = false;
  std::mutex session_mutex_;
  std::shared_ptr<Session> session_;
  std::string session_name_;
};

// ---------------------------------------------------------------------------
// Subscribe: follow a session's frames.

class SubscribeReactor final : public grpc::ServerWriteReactor<v1::TrackMessage>, public OutboxTarget {
 public:
  SubscribeReactor(LipSyncService& service, grpc::CallbackServerContext* context,
                   const v1::SubscribeRequest& request)
      : service_(service),
        context_(context),
        session_name_(request.session()),
        started_(Clock::now()),
        outbox_(std::make_shared<Outbox>(
            *this, service.config().subscriber_queue_frames,
            "subscriber fell behind: more than " + std::to_string(service.config().subscriber_queue_frames) +
                " frames waiting (--subscriber-queue-frames=" +
                std::to_string(service.config().subscriber_queue_frames) + ")")) {
    const grpc::Status admission = service_.admit_stream();
    if (!admission.ok()) {
      outbox_->close(admission);
      return;
    }
    admitted_ = true;
    session_ = service_.sessions().find(session_name_);
    if (!session_) {
      outbox_->close({grpc::StatusCode::NOT_FOUND,
                      "no session named '" + session_name_ + "' (never opened, or ended more than " +
                          std::to_string(service_.config().session_retention_ms) + " ms ago)"});
      return;
    }
    const bool from_beginning = request.start() != v1::SubscribeRequest::START_FROM_NOW;
    const grpc::Status attached =
        session_->attach(outbox_, from_beginning, service_.config().max_subscribers_per_session);
    if (!attached.ok()) outbox_->close(attached);
  }

  void OnWriteDone(bool ok) override { outbox_->on_write_done(ok); }
  void OnCancel() override { outbox_->abort(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled")); }

  void OnDone() override {
    stall_guard_->release();
    if (session_) session_->detach(outbox_.get());
    const auto status = outbox_->final_status().value_or(grpc::Status::OK);
    if (admitted_) {
      spdlog::info("Subscribe end peer={} session='{}' frames={} duration_ms={:.1f} status={}", context_->peer(),
                   session_name_, frames_sent_, elapsed_ms(started_), status_name(status));
      service_.release_stream();
    } else {
      spdlog::warn("Subscribe refused peer={} status={}", context_->peer(), status_name(status));
    }
    delete this;
  }

  void start_write(const v1::TrackMessage* message) override {
    if (message->has_frames()) frames_sent_ += static_cast<std::uint64_t>(message->frames().t_us_size());
    StartWrite(message);
  }
  void finish(const grpc::Status& status) override { Finish(status); }

  // Cut off with a write in flight: that write only completes when the client
  // reads, and Finish must wait for it. Give the client the grace period to
  // read on (it then gets RESOURCE_EXHAUSTED), else cancel the call.
  void on_stalled() override {
    const auto deadline = std::chrono::system_clock::now() +
                          std::chrono::milliseconds(service_.config().stalled_subscriber_ms);
    stall_alarm_.Set(deadline, [guard = stall_guard_](bool fired) {
      if (fired) guard->cancel();
    });
  }

 private:
  /// Lets the alarm cancel the call only while the reactor still exists.
  class StallGuard {
   public:
    explicit StallGuard(grpc::CallbackServerContext* context) : context_(context) {}
    void cancel() {
      std::lock_guard lock(mutex_);
      if (!context_) return;
      spdlog::warn("Subscribe cancelled peer={}: it stopped reading after it was cut off", context_->peer());
      context_->TryCancel();
    }
    void release() {
      std::lock_guard lock(mutex_);
      context_ = nullptr;
    }

   private:
    std::mutex mutex_;
    grpc::CallbackServerContext* context_;
  };

  LipSyncService& service_;
  grpc::CallbackServerContext* context_;
  const std::string session_name_;
  const Clock::time_point started_;
  std::shared_ptr<Outbox> outbox_;
  std::shared_ptr<Session> session_;
  bool admitted_ = false;
  std::uint64_t frames_sent_ = 0;
  std::shared_ptr<StallGuard> stall_guard_ = std::make_shared<StallGuard>(context_);
  grpc::Alarm stall_alarm_;
};

grpc::Status render(LipSyncService& service, const v1::RenderRequest& request, v1::RenderResponse& response) {
  const ServerConfig& config = service.config();
  Plan plan;
  if (auto status = resolve_settings(request.settings(), service.catalog(), false, plan); !status.ok()) {
    return status;
  }
  if (static_cast<std::size_t>(request.phonemes_size()) > config.max_phonemes) {
    return too_many_phonemes(config.max_phonemes);
  }
  const ArticulationModel& model = *plan.model->model;
  SegmentBuilder builder(model, *plan.phone_set, kStreamSource, plan.segment);
  std::vector<Segment> segments;
  int index = 0;
  for (const v1::Phoneme& phoneme : request.phonemes()) {
    ++index;
    try {
      builder.push(to_interval(phoneme, index), segments);
    } catch (const InputError& error) {
      return invalid(error.what());
    }
    if (builder.end_us() > config.max_utterance_ms * 1000) {
      return too_long(index, builder.end_us(), config.max_utterance_ms);
    }
  }
  FaceSetup face_setup;
  if (auto status = prepare_face(plan, service.faces(), face_setup); !status.ok()) return status;
  std::unique_ptr<FaceStream> face_stream;
  if (plan.mesh) {
    face_stream = std::make_unique<FaceStream>(
        *face_setup.topology, service.faces().solver(*face_setup.topology, *face_setup.rig), plan.mesh_encoding);
  }
  const Track track = render_track(plan.model->tables, segments, plan.render);
  *response.mutable_header() = plan.header;
  encode_frames(plan, track, 0, track.frame_count(), 0, *response.mutable_frames(), face_stream.get());
  response.mutable_summary()->set_frames(track.frame_count());
  response.mutable_summary()->set_phonemes(static_cast<std::uint64_t>(request.phonemes_size()));
  response.mutable_summary()->set_duration_us(builder.end_us());
  return grpc::Status::OK;
}

void describe(const ModelEntry& entry, v1::ModelInfo& info) {
  info.set_name(entry.name);
  for (const ChannelSpec& spec : entry.model->channels()) {
    auto& channel = *info.add_channels();
    channel.set_name(spec.name);
    channel.set_kind(spec.kind);
    channel.set_min(spec.min);
    channel.set_max(spec.max);
    channel.set_rest(spec.rest);
    channel.set_description(spec.description);
  }
  for (const auto name : kArkitNames) info.add_arkit_names(std::string(name));
  for (const PhonemeSpec& phoneme : entry.model->phonemes()) info.add_phonemes(phoneme.name);
  for (const PhoneSet& set : entry.phone_sets) info.add_phone_sets(set.name());
  info.set_is_default(entry.is_default);
}

template <class Function>
grpc::Status run_unary(grpc::CallbackServerContext* context, const char* method, Function&& function) {
  grpc::Status status;
  try {
    status = function();
  } catch (const std::exception& error) {
    status = grpc::Status(grpc::StatusCode::INTERNAL, error.what());
  }
  if (!status.ok()) spdlog::info("{} peer={} status={}", method, context->peer(), status_name(status));
  return status;
}

template <class Function>
grpc::ServerUnaryReactor* unary(grpc::CallbackServerContext* context, const char* method, Function&& function) {
  auto* reactor = context->DefaultReactor();
  reactor->Finish(run_unary(context, method, std::forward<Function>(function)));
  return reactor;
}


}  // namespace

LipSyncService::LipSyncService(const ServerConfig& config, const ModelCatalog& catalog)
    : config_(config),
      catalog_(catalog),
      sessions_(config.max_sessions, config.replay_frames, std::chrono::milliseconds(config.session_retention_ms)),
      face_workers_(config.face_threads > 0 ? config.face_threads : std::max(1u, std::thread::hardware_concurrency()),
                    config.face_priority == "idle"  ? FaceWorkers::Priority::idle
                    : config.face_priority == "low" ? FaceWorkers::Priority::low
                                                    : FaceWorkers::Priority::normal) {}

grpc::Status unavailable_while_draining() {
  return {grpc::StatusCode::UNAVAILABLE, "the server is shutting down"};
}

grpc::Status LipSyncService::admit_render() {
  ++calls_in_progress_;
  if (draining_) {
    --calls_in_progress_;
    return unavailable_while_draining();
  }
  return grpc::Status::OK;
}

grpc::Status LipSyncService::admit_stream() {
  ++calls_in_progress_;
  if (draining_) {
    --calls_in_progress_;
    return unavailable_while_draining();
  }
  std::size_t open = active_streams_.load();
  do {
    if (open >= config_.max_streams) {
      --calls_in_progress_;
      return {grpc::StatusCode::RESOURCE_EXHAUSTED,
              "the server already has " + std::to_string(open) + " open streams (--max-streams=" +
                  std::to_string(config_.max_streams) + ")"};
    }
  } while (!active_streams_.compare_exchange_weak(open, open + 1));
  return grpc::Status::OK;
}

grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage>* LipSyncService::Animate(
    grpc::CallbackServerContext* context) {
  return new AnimateReactor(*this, context);
}

grpc::ServerWriteReactor<v1::TrackMessage>* LipSyncService::Subscribe(grpc::CallbackServerContext* context,
                                                                      const v1::SubscribeRequest* request) {
  return new SubscribeReactor(*this, context, *request);
}

grpc::ServerUnaryReactor* LipSyncService::Render(grpc::CallbackServerContext* context,
                                                 const v1::RenderRequest* request, v1::RenderResponse* response) {
  if (grpc::Status admission = admit_render(); !admission.ok()) {
    return unary(context, "Render", [&] { return admission; });
  }
  if (!wants_mesh(request->settings())) {
    auto* reactor = unary(context, "Render", [&] { return render(*this, *request, *response); });
    release_render();
    return reactor;
  }
  // Seconds of solver work for a long utterance: off the reaction (face_workers.hpp).
  auto* reactor = context->DefaultReactor();
  face_workers_.post([this, context, request, response, reactor] {
    reactor->Finish(run_unary(context, "Render", [&] { return render(*this, *request, *response); }));
    release_render();
  });
  return reactor;
}

grpc::ServerUnaryReactor* LipSyncService::ListModels(grpc::CallbackServerContext* context,
                                                     const v1::ListModelsRequest*,
                                                     v1::ListModelsResponse* response) {
  return unary(context, "ListModels", [&] {
    for (const auto& entry : catalog_.entries()) describe(*entry, *response->add_models());
    return grpc::Status::OK;
  });
}

grpc::ServerUnaryReactor* LipSyncService::GetModel(grpc::CallbackServerContext* context,
                                                   const v1::GetModelRequest* request, v1::ModelInfo* response) {
  return unary(context, "GetModel", [&] {
    const ModelEntry* entry = catalog_.find(request->name());
    if (!entry) {
      return grpc::Status(grpc::StatusCode::NOT_FOUND,
                          "no model named '" + request->name() + "' (known: " + catalog_.names() + ")");
    }
    describe(*entry, *response);
    return grpc::Status::OK;
  });
}

}  // namespace lipsync::server
