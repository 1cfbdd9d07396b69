// Where Speak synthesises: one thread of its own, off gRPC's reactions.
//
// espeak-ng keeps its state (voice, parameters, output buffers, the callback)
// in process-wide globals and is not re-entrant; lipsync::speech::synthesize
// runs each synthesis in a child process of its own and holds one global mutex
// for it. Several threads would only queue on that mutex, so Speak calls run
// one at a time on this single thread, in arrival order. A synthesis takes tens of milliseconds to a few seconds
// (docs/server.md, "Speak"), which no reaction may spend. At most
// kMaxSpeakCalls calls wait for or run on the thread; a call beyond that is
// refused with RESOURCE_EXHAUSTED, so a burst of Speak calls cannot queue
// unbounded work.
#pragma once

#include <grpcpp/support/status.h>

#include <atomic>
#include <boost/asio/thread_pool.hpp>
#include <cstddef>
#include <functional>

namespace lipsync::server {

class SpeechThread {
 public:
  /// Speak calls waiting for or running on the thread at most.
  static constexpr std::size_t kMaxSpeakCalls = 32;

  SpeechThread();
  /// Runs what is still queued, then joins.
  ~SpeechThread();
  SpeechThread(const SpeechThread&) = delete;
  SpeechThread& operator=(const SpeechThread&) = delete;

  /// Queues `job` behind the calls already there, or returns RESOURCE_EXHAUSTED
  /// (and drops it) when kMaxSpeakCalls are there already.
  grpc::Status post(std::function<void()> job);

 private:
  std::atomic<std::size_t> calls_{0};
  boost::asio::thread_pool pool_{1};
};

}  // namespace lipsync::server
