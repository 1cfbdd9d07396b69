// The streams (Animate, Subscribe) running now, so that a drain whose deadline
// has passed can end them itself with ABORTED (docs/server.md, "Shutdown")
// before gRPC's Shutdown cancels whatever is left (the client would see
// UNAVAILABLE "Cancelling all calls"). A stream adds itself once admitted and
// removes itself first thing in OnDone, so every stream in the set is alive while
// the set's lock is held. abort_all calls into the streams under that lock; this
// cannot deadlock with OnDone because gRPC never runs OnDone of a streaming
// reactor inside Finish (it schedules it on its own executor).
#pragma once

#include <grpcpp/support/status.h>

#include <cstddef>
#include <mutex>
#include <unordered_set>

namespace lipsync::server {

class AbortableStream {
 public:
  /// Ends the stream with `status` at once (queued messages dropped). Called from the
  /// draining thread; thread-safe against the stream's own reactions.
  virtual void abort_stream(const grpc::Status& status) = 0;

 protected:
  ~AbortableStream() = default;
};

class LiveStreams {
 public:
  void add(AbortableStream& stream) {
    std::lock_guard lock(mutex_);
    streams_.insert(&stream);
  }
  void remove(AbortableStream& stream) {
    std::lock_guard lock(mutex_);
    streams_.erase(&stream);
  }
  /// Aborts every stream still running with `status`; returns how many.
  std::size_t abort_all(const grpc::Status& status) {
    std::lock_guard lock(mutex_);
    for (AbortableStream* stream : streams_) stream->abort_stream(status);
    return streams_.size();
  }

 private:
  std::mutex mutex_;
  std::unordered_set<AbortableStream*> streams_;
};

}  // namespace lipsync::server
