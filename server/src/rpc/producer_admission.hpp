// How a producer stream (Animate, Listen) comes in, stated once: a place under the server's stream
// admission (refused while draining or over --max-streams), its entry in the live streams (so that a
// drain past its deadline can abort it), the Outbox's metrics, the caller's tenant authenticated, the
// open-streams gauge (Animate's; Listen has none), and one unit of the tenant's stream quota. admit()
// takes them in that order and returns the first refusal, which the reactor closes with; in OnDone,
// leave_live_streams() comes first (before the reactor logs its end) and give_back() after it. The
// quota unit is held until the reactor, and this with it, is deleted. Used from the reactor's
// reactions only, which gRPC runs one at a time.
#pragma once

#include <grpcpp/grpcpp.h>

#include "call_log.hpp"
#include "rpc/outbox.hpp"
#include "rpc/service.hpp"
#include "sessions/live_streams.hpp"

namespace lipsync::server {

/// Backpressure on a producer that reads its frames slower than it sends their input (phonemes,
/// audio): with more than kReadPauseFrames frames waiting for it (queued for writing, or for its
/// face), the stream stops reading, so HTTP/2 flow control holds the client back; it reads again
/// once at most kReadResumeFrames wait. 4096 frames are 2.3 minutes at 30 frames/s.
constexpr std::size_t kReadPauseFrames = 4096;
constexpr std::size_t kReadResumeFrames = 1024;

class ProducerAdmission {
 public:
  /// `method` names the call to the tenants' authentication; `gauge_method`, when not null, is the
  /// method label of lipsyncd_streams the stream is counted under.
  ProducerAdmission(LipSyncService& service, const char* method, const char* gauge_method)
      : service_(service), method_(method), gauge_method_(gauge_method) {}

  grpc::Status admit(grpc::CallbackServerContext& context, AbortableStream& stream, Outbox& outbox, CallLog& log,
                     Caller& caller) {
    if (auto status = service_.admission().admit_stream(context.peer()); !status.ok()) return status;
    admitted_ = true;
    service_.live_streams().add(stream);
    outbox.measure(service_.metrics().write_latency, service_.metrics().queued_messages);
    if (auto status = service_.tenants().authenticate(context, method_, caller); !status.ok()) return status;
    log.set_tenant(caller.tenant());
    if (gauge_method_ != nullptr) {
      open_stream_ = &service_.metrics().open_streams.with({gauge_method_, caller.tenant()});
      open_stream_->add(1);
    }
    return caller.hold(Quota::streams, stream_hold_);
  }

  /// First thing in OnDone: the drain no longer sees the stream.
  void leave_live_streams(AbortableStream& stream) {
    if (admitted_) service_.live_streams().remove(stream);
  }
  /// In OnDone, after the end is logged: the gauge and the admission's place given back.
  void give_back() {
    if (open_stream_ != nullptr) open_stream_->add(-1);
    if (admitted_) service_.admission().release_stream();
  }

 private:
  LipSyncService& service_;
  const char* method_;
  const char* gauge_method_;
  bool admitted_ = false;
  Level* open_stream_ = nullptr;  // lipsyncd_streams{method, tenant}, once authenticated
  QuotaHold stream_hold_;
};

}  // namespace lipsync::server
