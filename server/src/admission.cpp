// Stream and call counting (admission.hpp). A call is counted in before
// `draining_` is read, so a drain that sees no call in progress has no call
// that could still slip in.
#include "admission.hpp"

#include <string>

namespace lipsync::server {

grpc::Status Admission::admit_call() {
  ++calls_in_progress_;
  if (draining_) {
    --calls_in_progress_;
    return {grpc::StatusCode::UNAVAILABLE, "the server is shutting down"};
  }
  return grpc::Status::OK;
}

grpc::Status Admission::admit_render() { return admit_call(); }

grpc::Status Admission::admit_stream() {
  if (grpc::Status status = admit_call(); !status.ok()) return status;
  std::size_t open = active_streams_.load();
  do {
    if (open >= max_streams_) {
      --calls_in_progress_;
      return {grpc::StatusCode::RESOURCE_EXHAUSTED,
              "the server already has " + std::to_string(open) + " open streams (--max-streams=" +
                  std::to_string(max_streams_) + ")"};
    }
  } while (!active_streams_.compare_exchange_weak(open, open + 1));
  return grpc::Status::OK;
}

}  // namespace lipsync::server
