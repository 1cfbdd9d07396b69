// Admission control: which calls the server takes on. Animate and Subscribe
// streams count against --max-streams (RESOURCE_EXHAUSTED beyond it); every
// Animate, Subscribe and Render call counts as "in progress" so that a drain
// (SIGTERM) can wait for them; once draining, new calls get UNAVAILABLE. The
// callback thread pool cannot be tuned in gRPC 1.51, so these counts are the
// server's only limit. Lock-free: every call start and end passes here.
#pragma once

#include <atomic>
#include <cstddef>

#include <grpcpp/support/status.h>

namespace lipsync::server {

class Admission {
 public:
  explicit Admission(std::size_t max_streams) : max_streams_(max_streams) {}

  /// Counts a new stream in, or says which limit it is over (or that the server is draining).
  grpc::Status admit_stream();
  void release_stream() {
    --active_streams_;
    --calls_in_progress_;
  }
  /// Render calls: counted for the drain only (they are not streams).
  grpc::Status admit_render();
  void release_render() { --calls_in_progress_; }

  /// From now on new calls are refused with UNAVAILABLE.
  void begin_drain() { draining_ = true; }
  /// Animate and Subscribe streams open.
  std::size_t active_streams() const { return active_streams_.load(); }
  /// Animate, Subscribe and Render calls running.
  std::size_t calls_in_progress() const { return calls_in_progress_.load(); }

 private:
  /// Counts a call in unless the server is draining.
  grpc::Status admit_call();

  const std::size_t max_streams_;
  std::atomic<std::size_t> active_streams_{0};
  std::atomic<std::size_t> calls_in_progress_{0};
  std::atomic<bool> draining_{false};
};

}  // namespace lipsync::server
