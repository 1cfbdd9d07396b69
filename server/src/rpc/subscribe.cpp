// Subscribe: follow a named session's messages (session.hpp) from the
// beginning (what the session still holds) or from now, through an Outbox
// with a bounded queue. It is a raw method (service.hpp): it writes each
// message's bytes, serialised once per session and shared by all its
// subscribers, and parses its SubscribeRequest itself. A subscriber that falls more than
// --subscriber-queue-frames behind is cut off with RESOURCE_EXHAUSTED; if it
// has also stopped reading, so that even that status cannot leave, an alarm
// cancels the call after --stalled-subscriber-ms. The reactor is local to this
// file and made by LipSyncService::Subscribe at its end.
#include <grpcpp/alarm.h>
#include <grpcpp/impl/codegen/proto_utils.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <string>

#include "call_log.hpp"
#include "lipsync/tsan_handoff.hpp"
#include "rpc/outbox.hpp"
#include "rpc/service.hpp"
#include "sessions/live_streams.hpp"

namespace lipsync::server {
namespace {

class SubscribeReactor final : public HandoffReactor<grpc::ServerWriteReactor<grpc::ByteBuffer>>,
                               public OutboxTarget,
                               public AbortableStream {
 public:
  SubscribeReactor(LipSyncService& service, grpc::CallbackServerContext* context, const v1::SubscribeRequest& request,
                   const grpc::Status& parsed)
      : service_(service),
        context_(context),
        session_name_(request.session()),
        log_("Subscribe", *context, &service.metrics()),
        frames_counter_(service.metrics().frames_sent.with({"Subscribe"})),
        messages_counter_(service.metrics().messages_sent.with({"Subscribe"})),
        outbox_(std::make_shared<Outbox>(*this, service.config().subscriber_queue_frames,
                                         "subscriber fell behind: more than " +
                                             std::to_string(service.config().subscriber_queue_frames) +
                                             " frames waiting (--subscriber-queue-frames=" +
                                             std::to_string(service.config().subscriber_queue_frames) + ")")) {
    const grpc::Status admission = service_.admission().admit_stream(context_->peer());
    if (!admission.ok()) {
      outbox_->close(admission);
      return;
    }
    admitted_ = true;
    service_.live_streams().add(*this);
    outbox_->measure(service_.metrics().write_latency, service_.metrics().queued_messages);
    log_.set_session(session_name_);
    if (auto status = service_.tenants().authenticate(*context_, "Subscribe", caller_); !status.ok()) {
      outbox_->close(status);  // logged by the end line, as a refused Animate is
      return;
    }
    log_.set_tenant(caller_.tenant());
    log_.started_line({{"start", v1::SubscribeRequest::Start_Name(request.start())}});
    open_stream_ = &service_.metrics().open_streams.with({"Subscribe", caller_.tenant()});
    open_stream_->add(1);
    for (auto [quota, hold] : {std::pair{Quota::streams, &stream_hold_}, {Quota::subscribers, &subscriber_hold_}}) {
      if (auto status = caller_.hold(quota, *hold); !status.ok()) {
        outbox_->close(status);
        return;
      }
    }
    if (!parsed.ok()) {
      outbox_->close(parsed);
      return;
    }
    if (auto routed = service_.routing().check_metadata(*context_, session_name_); !routed.ok()) {
      outbox_->close(routed);
      return;
    }
    // Another tenant's session is not found, with the same words as one that does not exist.
    session_ = service_.sessions().find(caller_.session_key(session_name_));
    if (!session_) {
      outbox_->close(service_.routing().not_held(session_name_, service_.config().session_retention_ms));
      return;
    }
    const bool from_beginning = request.start() != v1::SubscribeRequest::START_FROM_NOW;
    const grpc::Status attached =
        session_->attach(outbox_, from_beginning, service_.config().max_subscribers_per_session);
    if (!attached.ok()) outbox_->close(attached);
  }

  void OnWriteDone(bool ok) override {
    const HandoffScope handoff = reaction();
    outbox_->on_write_done(ok);
  }
  void OnCancel() override {
    const HandoffScope handoff = reaction();
    cancelled_ = true;
    outbox_->abort(cancelled_status());
  }
  void abort_stream(const grpc::Status& status) override { outbox_->abort(status); }

  void OnDone() override {
    last_reaction();
    if (admitted_) service_.live_streams().remove(*this);
    stall_guard_->release();
    if (session_) session_->detach(outbox_.get());
    const auto status = cancelled_ ? cancelled_status() : outbox_->final_status().value_or(grpc::Status::OK);
    log_.ended(status, {{"frames", frames_sent_}});
    if (open_stream_) open_stream_->add(-1);
    if (admitted_) service_.admission().release_stream();
    service_.call_ended();
    delete this;
  }

  void start_write(const OutgoingMessage& message) override {
    messages_counter_.add();
    if (message.message().has_frames()) {
      frames_sent_ += static_cast<std::uint64_t>(message.message().frames().t_us_size());
      frames_counter_.add(static_cast<std::uint64_t>(message.message().frames().t_us_size()));
    }
    StartWrite(&message.bytes());
  }
  void finish(const grpc::Status& status) override { Finish(status); }

  // Cut off with a write in flight: that write only completes when the client
  // reads, and Finish must wait for it. Give the client the grace period to
  // read on (it then gets RESOURCE_EXHAUSTED), else cancel the call.
  void on_stalled() override {
    const auto deadline =
        std::chrono::system_clock::now() + std::chrono::milliseconds(service_.config().stalled_subscriber_ms);
    stall_alarm_.Set(deadline, [guard = stall_guard_](bool fired) {
      if (fired) guard->cancel();
    });
  }

 private:
  /// Lets the alarm cancel the call only while the reactor still exists.
  class StallGuard {
   public:
    StallGuard(grpc::CallbackServerContext* context, const CallLog& log) : context_(context), log_(log) {}
    void cancel() {
      std::lock_guard lock(mutex_);
      if (!context_) return;
      log_.line(spdlog::level::warn, "stalled", "cancelled: it stopped reading after it was cut off");
      context_->TryCancel();
    }
    void release() {
      std::lock_guard lock(mutex_);
      context_ = nullptr;
    }

   private:
    std::mutex mutex_;
    grpc::CallbackServerContext* context_;
    const CallLog& log_;  // the reactor's: used only while context_ is set
  };

  LipSyncService& service_;
  grpc::CallbackServerContext* context_;
  const std::string session_name_;
  const Clock::time_point started_;
  Caller caller_;  // the tenant; its quotas are held until the reactor is deleted
  QuotaHold stream_hold_, subscriber_hold_;
  CallLog log_;
  Counter& frames_counter_;
  Counter& messages_counter_;
  std::atomic<bool> cancelled_ = false;
  std::shared_ptr<Outbox> outbox_;
  std::shared_ptr<Session> session_;
  bool admitted_ = false;
  Level* open_stream_ = nullptr;  // lipsyncd_streams{method="Subscribe",tenant}, once authenticated
  std::uint64_t frames_sent_ = 0;
  std::shared_ptr<StallGuard> stall_guard_ = std::make_shared<StallGuard>(context_, log_);
  grpc::Alarm stall_alarm_;
};

}  // namespace

grpc::ServerWriteReactor<grpc::ByteBuffer>* LipSyncService::Subscribe(grpc::CallbackServerContext* context,
                                                                      const grpc::ByteBuffer* raw_request) {
  handoff_acquire(this);  // the service as built before the server started (tsan_handoff.hpp)
  v1::SubscribeRequest request;
  grpc::ByteBuffer bytes = *raw_request;  // Deserialize consumes its buffer; this copy only refs the slices
  const grpc::Status parsed = grpc::SerializationTraits<v1::SubscribeRequest>::Deserialize(&bytes, &request);
  auto* reactor = new SubscribeReactor(
      *this, context, request,
      parsed.ok() ? grpc::Status::OK
                  : grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                                 "Subscribe: the request is not a SubscribeRequest (" + parsed.error_message() + ")"));
  reactor->handed_off();
  return reactor;
}

}  // namespace lipsync::server
