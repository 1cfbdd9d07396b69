// Stream and call counting (admission.hpp). A call is counted in before
// `draining_` is read, so a drain that sees no call in progress has no call
// that could still slip in.
#include "admission.hpp"

#include <string>

namespace lipsync::server {

grpc::Status Admission::admit_call(std::string_view peer) {
  const std::size_t calls = ++calls_in_progress_;
  if (observer_) observer_(calls);
  const auto first_call_of_connection_accepted_at = connections_.first_call(peer);
  if (draining_) {
    const bool balancer_session_on_its_way =
        first_call_of_connection_accepted_at &&
        *first_call_of_connection_accepted_at >= drain_started_.load() - kFirstCallWindow;
    if (!balancer_session_on_its_way) {
      call_ended();
      return {grpc::StatusCode::UNAVAILABLE, "the server is shutting down"};
    }
  }
  return grpc::Status::OK;
}

void Admission::begin_drain() {
  drain_started_ = ConnectionLedger::Clock::now();
  draining_ = true;
}

bool Admission::awaiting_first_calls() const {
  return connections_.awaiting_first_call(ConnectionLedger::Clock::now() - kFirstCallWindow);
}

grpc::Status Admission::admit_render(std::string_view peer) { return admit_call(peer); }

grpc::Status Admission::admit_stream(std::string_view peer) {
  if (grpc::Status status = admit_call(peer); !status.ok()) return status;
  std::size_t open = active_streams_.load();
  do {
    if (open >= max_streams_) {
      call_ended();
      return {grpc::StatusCode::RESOURCE_EXHAUSTED, "the server already has " + std::to_string(open) +
                                                        " open streams (--max-streams=" + std::to_string(max_streams_) +
                                                        ")"};
    }
  } while (!active_streams_.compare_exchange_weak(open, open + 1));
  return grpc::Status::OK;
}

}  // namespace lipsync::server
