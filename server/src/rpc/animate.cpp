// Animate: one bidirectional stream per utterance. Settings first, then
// phoneme chunks, then `end`; back come a header, frame batches as the
// incremental renderer releases them, and a summary. The reactor is local to
// this file and made by LipSyncService::Animate at its end.
//
// Reactions never block: the engine costs about a microsecond per frame, so
// frames are computed in OnReadDone, and writes go through an Outbox (one write
// in flight, Finish only when none is). A producer that reads its frames slower
// than it sends phonemes is held back: while thousands of its frames wait, its
// stream reads no more phonemes, and HTTP/2 flow control stops the client.
// With a session name, every message is published to the session first, so
// subscribers (subscribe.cpp) see what the producer sees.
//
// The mesh output (face_stream.hpp) is the exception to "cheap": a FaceSolver
// costs about a millisecond per frame and tens of ms to build (streams take
// built ones from a pool when they can). A stream that asks for it gets a
// FaceLane (face_workers.hpp): its solver is built, its frames are encoded and
// everything it sends after its header (frames, summary, Finish) leaves from
// low-priority face threads, in order; the reactions only queue the released
// frames. Streams that do not ask for the mesh never create or touch a solver
// or a lane. A mesh stream is admitted against the face's capacity
// (face_capacity.hpp: RESOURCE_EXHAUSTED beyond it) and ends with
// DEADLINE_EXCEEDED if its face falls more than --mesh-max-lag-ms behind real
// time.
//
// The producer may attach the utterance's sound to its session (AudioAttachment,
// between the settings and the first phonemes, in pieces): the pieces are
// gathered, checked as one WAV file when the first phonemes (or `end`) arrive,
// and kept by the session before any of its frames are published, so that the
// browser viewer serves it (/audio?session=NAME) as it serves a Speak session's.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "call_log.hpp"
#include "lipsync/error.hpp"
#include "lipsync/excerpt.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/tsan_handoff.hpp"
#include "rpc/outbox.hpp"
#include "rpc/phoneme_input.hpp"
#include "rpc/plan.hpp"
#include "rpc/producer_admission.hpp"
#include "rpc/service.hpp"
#include "rpc/wire.hpp"
#include "sessions/live_streams.hpp"

namespace lipsync::server {
namespace {

// Frames the track of released frames has room for from the start.
constexpr std::size_t kTypicalReleaseFrames = 16;
// The most audio a producer may attach to its session (AudioAttachment, all pieces): about 3 minutes
// of 48 kHz stereo 16-bit sound, kept as long as the session.
constexpr std::size_t kMaxAttachedAudioBytes = 32 * 1024 * 1024;

class AnimateReactor final : public HandoffReactor<grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage>>,
                             public OutboxTarget,
                             public AbortableStream {
 public:
  AnimateReactor(LipSyncService& service, grpc::CallbackServerContext* context)
      : service_(service),
        context_(context),
        outbox_(*this),
        log_("Animate", *context, &service.metrics()),
        frames_counter_(service.metrics().frames_sent.with({"Animate"})),
        messages_counter_(service.metrics().messages_sent.with({"Animate"})),
        admission_(service, "Animate", "Animate") {
    if (auto status = admission_.admit(*context_, *this, outbox_, log_, caller_); !status.ok()) {
      outbox_.close(status);
      return;
    }
    StartRead(&request_);
  }

  void OnReadDone(bool ok) override {
    const HandoffScope handoff = reaction();
    if (!ok) {
      if (phase_ == Phase::ended) {
        in_order([this] { outbox_.close(grpc::Status::OK); });
      } else {
        // gRPC ends the reads the same way when the client closes its side and when a
        // message cannot be decoded as an AnimateRequest; a cancel is told apart in OnDone.
        fail(invalid("the request stream ended before `end` after " + std::to_string(phonemes()) +
                     " phonemes: the client closed its side, or sent a message that is not an AnimateRequest"),
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
    const HandoffScope handoff = reaction();
    outbox_.on_write_done(ok);
    std::lock_guard lock(flow_mutex_);
    if (read_paused_ && frames_waiting() <= kReadResumeFrames) {
      read_paused_ = false;
      StartRead(&request_);
    }
  }

  void OnCancel() override {
    const HandoffScope handoff = reaction();
    cancelled_ = true;
    stopped_ = true;
    outbox_.abort(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
    fail_session("producer disconnected: the stream was cancelled");
  }

  void OnDone() override {
    last_reaction();
    admission_.leave_live_streams(*this);
    const auto status = cancelled_ ? cancelled_status() : outbox_.final_status().value_or(grpc::Status::OK);
    log_.ended(status, {{"phonemes", static_cast<std::uint64_t>(phonemes())}, {"frames", frames_sent_.load()}});
    admission_.give_back();
    stopped_ = true;
    if (mesh_weight_milli_ > 0) service_.face_capacity().release(mesh_weight_milli_);
    if (audio_reserved_bytes_ > 0) service_.audio_budget().release(audio_reserved_bytes_);
    service_.call_ended();
    if (lane_) {
      lane_->retire([this] { delete this; });  // after the face jobs still queued
    } else {
      delete this;
    }
  }

  void start_write(const OutgoingMessage& message) override {
    messages_counter_.add();
    if (message.message().has_frames()) {
      frames_counter_.add(static_cast<std::uint64_t>(message.message().frames().t_us_size()));
    }
    StartWrite(&message.message());
  }
  void finish(const grpc::Status& status) override { Finish(status); }

  void abort_stream(const grpc::Status& status) override {
    stopped_ = true;
    outbox_.abort(status);
    fail_session("the server shut down: " + status.error_message());
  }

 private:
  enum class Phase { awaiting_settings, streaming, ended };

  grpc::Status handle(const v1::AnimateRequest& request) {
    switch (phase_) {
      case Phase::awaiting_settings:
        if (!request.has_settings()) return invalid("first message must be settings");
        return start(request.settings());
      case Phase::streaming:
        if (request.has_audio()) return attach_audio(request.audio());
        if (request.has_phonemes()) {
          if (auto status = keep_attached_audio(); !status.ok()) return status;
          return add_phonemes(request.phonemes());
        }
        if (request.has_end()) {
          if (auto status = keep_attached_audio(); !status.ok()) return status;
          return end();
        }
        if (request.has_settings()) return invalid("settings sent twice: only the first message may be settings");
        return invalid("empty AnimateRequest after " + std::to_string(phonemes()) + " phonemes");
      case Phase::ended:
        if (request.has_phonemes() && request.phonemes().phonemes_size() > 0) {
          const auto& phoneme = request.phonemes().phonemes(0);
          return invalid(std::string(kStreamSource) + ":" + std::to_string(phonemes() + 1) + ": phoneme " +
                         excerpt(phoneme.label()) + ": received after `end`");
        }
        return invalid("message received after `end` (the utterance had " + std::to_string(phonemes()) + " phonemes)");
    }
    return grpc::Status::OK;
  }

  /// Gathers one piece of the attached audio file (AudioAttachment.wav).
  grpc::Status attach_audio(const v1::AudioAttachment& audio) {
    if (!current_session()) {
      return invalid("audio: attached to a stream without settings.session: only a session keeps its audio");
    }
    if (audio_kept_ || phonemes() > 0) {
      return invalid("audio: sent after the first phonemes: attach the audio between the settings and them");
    }
    if (attached_audio_.size() + audio.wav().size() > kMaxAttachedAudioBytes) {
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                          "audio.wav: the attached audio is over " + std::to_string(kMaxAttachedAudioBytes) +
                              " bytes (32 MiB) with this piece of " + std::to_string(audio.wav().size()) + " bytes");
    }
    if (!service_.audio_budget().try_reserve(audio.wav().size())) {
      const AudioBudget& budget = service_.audio_budget();
      return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                          "audio.wav: the sessions' audio would be over the server's " +
                              std::to_string(budget.limit_bytes()) + " bytes (--max-session-audio-bytes) with this " +
                              "piece of " + std::to_string(audio.wav().size()) + " bytes (" +
                              std::to_string(budget.held_bytes()) + " held now): try again when sessions expire");
    }
    audio_reserved_bytes_ += audio.wav().size();
    attached_audio_ += audio.wav();
    return grpc::Status();
  }

  /// Once, when the first phonemes or `end` arrive: the gathered audio, checked as a WAV file,
  /// becomes the session's (before any frame is published).
  grpc::Status keep_attached_audio() {
    if (audio_kept_) return grpc::Status();
    audio_kept_ = true;
    if (attached_audio_.empty()) return grpc::Status();
    try {
      const auto [layout, duration_us] = speech::wav_layout_and_duration_us(attached_audio_, "audio.wav");
      log_.line(spdlog::level::debug, "audio attached",
                std::to_string(attached_audio_.size()) + " bytes, " + std::to_string(duration_us) + " us at " +
                    std::to_string(layout.sample_rate_hz) + " Hz");
    } catch (const InputError& error) {
      return invalid("audio.wav: " + error.message());
    }
    if (auto session = current_session()) {
      session->set_audio_wav(service_.audio_budget().keep(std::move(attached_audio_)));
      audio_reserved_bytes_ = 0;  // the kept string gives them back
    }
    attached_audio_ = std::string();
    return grpc::Status();
  }

  grpc::Status start(const v1::AnimationSettings& settings) {
    log_.set_session(settings.session());
    log_.started_line();
    if (auto status = service_.routing().check_metadata(*context_, settings.session()); !status.ok()) return status;
    if (auto status = resolve_settings(settings, service_.catalog(), true, plan_); !status.ok()) return status;
    if (auto status = prepare_face(plan_, service_.faces(), face_setup_); !status.ok()) return status;
    if (plan_.mesh) {
      if (auto status = caller_.hold(Quota::mesh_streams, mesh_hold_); !status.ok()) return status;
      const std::int64_t weight =
          FaceCapacity::weight_milli(plan_.engine.mesh_subdivision, plan_.engine.render.fps, plan_.mesh_solve);
      if (auto status = service_.face_capacity().admit(weight); !status.ok()) return status;
      mesh_weight_milli_ = weight;
      face_deadline_.emplace(FaceDeadline::Clock::now(), std::chrono::milliseconds(service_.config().mesh_max_lag_ms));
    }
    v1::TrackMessage header_message;
    // Moved, not copied: nothing reads the plan's header after this (its strings were an
    // allocation each, per stream).
    *header_message.mutable_header() = std::move(plan_.header);
    const Message header = make_message(std::move(header_message));
    if (!settings.session().empty()) {
      std::shared_ptr<Session> session;
      if (auto status = caller_.hold(Quota::sessions, session_hold_); !status.ok()) return status;
      if (auto status =
              service_.sessions().open(settings.session(), header, session, caller_.session_key(settings.session()));
          !status.ok()) {
        return status;
      }
      std::lock_guard lock(session_mutex_);
      session_ = std::move(session);
    }
    input_.emplace(plan_, service_.config());
    renderer_.emplace(plan_.model->tables, plan_.engine.render);
    track_.channel_count = plan_.model->model->channel_count();
    track_.fps = plan_.engine.render.fps;
    // What one read usually releases (a phoneme's frames; more at high rates or for a chunk of
    // many): the track is cleared, not freed, after each, so it rarely grows past this.
    track_.reserve(kTypicalReleaseFrames);
    outbox_.push(header);
    if (plan_.mesh) {
      // From here on everything that leaves this stream goes through the lane, in order.
      lane_.emplace(service_.face_workers());
      lane_->post([this, encoding = plan_.mesh_encoding, solve = plan_.mesh_solve, blinks = plan_.blinks] {
        if (!stopped_) {
          face_ = std::make_unique<FaceStream>(*face_setup_.topology,
                                               service_.faces().solver(*face_setup_.topology, *face_setup_.rig, solve),
                                               encoding, blinks);
        }
      });
    }
    phase_ = Phase::streaming;
    return grpc::Status::OK;
  }

  grpc::Status add_phonemes(const v1::PhonemeChunk& chunk) {
    if (auto status = caller_.take_phonemes(static_cast<std::size_t>(chunk.phonemes_size())); !status.ok()) {
      return status;
    }
    service_.metrics().phonemes_received.add(static_cast<std::uint64_t>(chunk.phonemes_size()));
    for (const v1::Phoneme& phoneme : chunk.phonemes()) {
      if (auto status = input_->push(phoneme, segments_); !status.ok()) return status;
      for (const Segment& segment : segments_) renderer_->push(segment, track_);
      segments_.clear();
    }
    send_frames(input_->newest_start_us());
    return grpc::Status();  // OK, without copying Status::OK (per read)
  }

  grpc::Status end() {
    renderer_->finish(track_);
    send_frames(input_->end_us());
    in_order([this, phonemes = phonemes(), duration_us = input_->end_us()] {
      v1::TrackMessage summary_message;
      encode_summary(frames_sent_, phonemes, duration_us, *summary_message.mutable_summary());
      const Message summary = make_message(std::move(summary_message));
      if (auto session = current_session()) session->finish(summary);
      outbox_.push(summary);
    });
    phase_ = Phase::ended;
    return grpc::Status::OK;
  }

  /// Sends the frames the renderer released since the last call, when the
  /// producer's input had reached utterance time `input_us`.
  void send_frames(std::int64_t input_us) {
    if (track_.frame_count() == 0) return;
    if (!lane_) {
      publish(track_, input_us);
      track_.clear();
      return;
    }
    auto released = std::make_shared<Track>();
    released->channel_count = track_.channel_count;
    released->fps = track_.fps;
    std::swap(*released, track_);
    frames_in_lane_ += released->frame_count();
    lane_->post([this, released, input_us, released_at = FaceDeadline::Clock::now()] {
      // Counted out before they reach the outbox, so the write completion that
      // follows sees them only there (and can resume reading).
      frames_in_lane_ -= released->frame_count();
      if (!stopped_) publish(*released, input_us, released_at);
    });
  }

  /// Phonemes received so far.
  std::size_t phonemes() const { return input_ ? input_->count() : 0; }

  std::size_t frames_waiting() const { return outbox_.queued_frames() + frames_in_lane_.load(); }

  /// Encodes and sends `track`'s frames; a mesh stream (released at `released_at`)
  /// first checks each batch against its face deadline and fails when it is late.
  void publish(const Track& track, std::int64_t input_us,
               FaceDeadline::Clock::time_point released_at = FaceDeadline::Clock::now()) {
    const std::size_t per_batch = face_setup_.frames_per_batch;
    for (std::size_t begin = 0; begin < track.frame_count(); begin += per_batch) {
      const std::size_t end = std::min(track.frame_count(), begin + per_batch);
      if (face_deadline_) {
        const auto due = face_deadline_->due(track.t_us[begin], released_at);
        if (auto late = face_deadline_->check(due, FaceDeadline::Clock::now()); !late.ok()) {
          fail(late, "producer failed: " + late.error_message());
          return;
        }
      }
      v1::TrackMessage batch;
      encoder_.face = face_.get();
      const auto encoding = Clock::now();
      encode_frames(plan_, track, begin, end, frames_sent_, *batch.mutable_frames(), encoder_);
      if (face_) service_.metrics().face_solver.observe_us(microseconds_since(encoding));
      batch.mutable_frames()->set_release_lag_us(input_us - track.t_us[begin]);
      const Message message = make_message(std::move(batch));
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
  Caller caller_;  // the tenant; its quotas are held until the reactor is deleted
  QuotaHold session_hold_, mesh_hold_;
  Outbox outbox_;
  CallLog log_;
  Counter& frames_counter_;
  Counter& messages_counter_;
  ProducerAdmission admission_;          // the stream quota's unit is held until the reactor is deleted
  std::atomic<bool> cancelled_ = false;  // OnCancel came: the client got CANCELLED (or gRPC's own status)
  Phase phase_ = Phase::awaiting_settings;
  v1::AnimateRequest request_;
  Plan plan_;
  std::optional<PhonemeInput> input_;
  std::optional<StreamingRenderer> renderer_;
  // Only when the mesh is asked for: the face is built and stepped on the lane.
  FaceSetup face_setup_;
  std::optional<FaceLane> lane_;
  std::int64_t mesh_weight_milli_ = 0;  // admitted against the face's capacity (0: no mesh)
  std::optional<FaceDeadline> face_deadline_;
  std::unique_ptr<FaceStream> face_;
  // The face (above) and this stream's viseme event detector; used where frames are encoded
  // (the reactions, or the lane for a mesh stream), one batch at a time, in order.
  StreamEncoder encoder_;
  std::atomic<bool> stopped_ = false;  // failed, cancelled or done: queued face work is skipped
  std::vector<Segment> segments_;
  std::string attached_audio_;            // AudioAttachment pieces gathered so far
  std::size_t audio_reserved_bytes_ = 0;  // of the server's audio budget, for attached_audio_ until kept
  bool audio_kept_ = false;               // the first phonemes or `end` came: no more audio
  Track track_;
  std::atomic<std::uint64_t> frames_sent_ = 0;
  std::atomic<std::size_t> frames_in_lane_ = 0;
  std::mutex flow_mutex_;  // orders the read-pause decision against write completions
  bool read_paused_ = false;
  std::mutex session_mutex_;
  std::shared_ptr<Session> session_;
};

}  // namespace

grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage>* LipSyncService::Animate(
    grpc::CallbackServerContext* context) {
  handoff_acquire(this);  // the service as built before the server started (tsan_handoff.hpp)
  auto* reactor = new AnimateReactor(*this, context);
  reactor->handed_off();
  return reactor;
}

}  // namespace lipsync::server
