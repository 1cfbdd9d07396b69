// Admission control: which calls the server takes on. Animate and Subscribe
// streams count against --max-streams (RESOURCE_EXHAUSTED beyond it); every
// Animate, Subscribe and Render call (and ListModels and GetModel, never refused)
// counts as "in progress" so that a drain (SIGTERM) can wait for them, and the
// service outlives everything they touch; once draining, new calls get UNAVAILABLE, except
// the first call of a connection accepted just before or while the listener
// closed (connection_ledger.hpp: a balancer's new session already on its way).
// The callback thread pool cannot be tuned in gRPC 1.51, so these counts are
// the server's only limit. The counts are lock-free; the ledger takes a mutex
// once per call start.
#pragma once

#include <grpcpp/support/status.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <functional>
#include <string_view>

#include "transport/connection_ledger.hpp"

namespace lipsync::server {

class Admission {
 public:
  explicit Admission(std::size_t max_streams) : max_streams_(max_streams) {}

  /// How long before the drain, or after its own acceptance, a connection's first call
  /// is still taken during a drain.
  static constexpr std::chrono::milliseconds kFirstCallWindow{500};

  /// Counts a new stream from `peer` (gRPC's peer name) in, or says which limit it is
  /// over (or that the server is draining).
  grpc::Status admit_stream(std::string_view peer);
  void release_stream() {
    --active_streams_;
    call_ended();
  }
  /// Render calls: counted for the drain only (they are not streams).
  grpc::Status admit_render(std::string_view peer);
  void release_render() { call_ended(); }
  /// ListModels and GetModel: counted so that the drain waits for their end (their access line
  /// and metrics), never refused (they change nothing and answer at once).
  void count_query() {
    const std::size_t calls = ++calls_in_progress_;
    if (observer_) observer_(calls);
  }
  void release_query() { call_ended(); }
  /// Called with the calls in progress each time they change (the transport quota follows them:
  /// transport_quota.hpp). Set once, before the server takes calls.
  void follow_calls(std::function<void(std::size_t)> observer) { observer_ = std::move(observer); }

  /// From now on new calls are refused with UNAVAILABLE (but for first calls, above).
  void begin_drain();
  /// During a drain: whether a connection accepted within kFirstCallWindow has not
  /// sent its first call yet (the drain waits for it).
  bool awaiting_first_calls() const;
  /// The listener's connections, for the listener to record what it accepts.
  ConnectionLedger& connections() { return connections_; }
  /// Animate and Subscribe streams open.
  std::size_t active_streams() const { return active_streams_.load(); }
  /// Animate, Subscribe, Render, ListModels and GetModel calls running.
  std::size_t calls_in_progress() const { return calls_in_progress_.load(); }

 private:
  /// Counts a call in unless the server is draining.
  grpc::Status admit_call(std::string_view peer);
  void call_ended() {
    const std::size_t calls = --calls_in_progress_;
    if (observer_) observer_(calls);
  }

  const std::size_t max_streams_;
  std::atomic<std::size_t> active_streams_{0};
  std::atomic<std::size_t> calls_in_progress_{0};
  std::atomic<bool> draining_{false};
  std::atomic<ConnectionLedger::Clock::time_point> drain_started_{ConnectionLedger::Clock::time_point::max()};
  ConnectionLedger connections_;
  std::function<void(std::size_t)> observer_;
};

}  // namespace lipsync::server
