// The outgoing side of one server stream: a queue of TrackMessages and the
// gRPC rule that at most one write is in flight and that Finish comes only when
// no write is outstanding.
//
// Messages are shared, immutable OutgoingMessages: a session hands the same one
// to its producer and every subscriber. A stream that writes typed messages
// (Animate) writes the protobuf; one that writes bytes (Subscribe, a raw
// method) writes the message's serialised form, which is made once, by the
// first stream that needs it, and then shared: every subscriber's write refers
// to the same slices (grpc::ByteBuffer copies by reference), so a batch is
// encoded once however many follow it.
//
// Anyone may push (a reaction, or a producer's thread fanning out to
// subscribers); the first push that finds the stream idle starts the write, and
// each write's completion (on_write_done) starts the next. StartWrite and Finish
// are called outside the lock. A bounded outbox (max_frames > 0) that would hold
// more counted frames ends the stream with RESOURCE_EXHAUSTED instead of
// growing: the pusher never waits on a slow reader. If a write is still in
// flight at that moment, the target hears of it (on_stalled) so that it can
// cancel a reader that never reads again.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include "lipsync/v1/lipsync.pb.h"
#include "metrics.hpp"

namespace lipsync::server {

/// One message as every stream that sends it shares it.
class OutgoingMessage {
 public:
  explicit OutgoingMessage(v1::TrackMessage message) : message_(std::move(message)) {}

  const v1::TrackMessage& message() const { return message_; }
  /// The serialised message: encoded on the first call (by whichever thread
  /// makes it), the same bytes for every later one.
  const grpc::ByteBuffer& bytes() const;

 private:
  v1::TrackMessage message_;
  // Double-checked, not std::call_once: call_once touches thread-local state on
  // every call, which callgrind showed at ~2 % of the server with fan-out.
  mutable std::atomic<bool> encoded_{false};
  mutable std::mutex encode_mutex_;
  mutable grpc::ByteBuffer bytes_;
};

using Message = std::shared_ptr<const OutgoingMessage>;

/// Wraps a finished protobuf message for sending (moved, not copied).
inline Message make_message(v1::TrackMessage&& message) {
  return std::make_shared<const OutgoingMessage>(std::move(message));
}

/// What an outbox drives: a reactor's StartWrite and Finish.
class OutboxTarget {
 public:
  /// Starts writing `message` (typed or as its bytes); it stays alive until on_write_done.
  virtual void start_write(const OutgoingMessage& message) = 0;
  virtual void finish(const grpc::Status& status) = 0;
  /// The bound overflowed while a write was in flight: Finish waits for that
  /// write, which never completes if the reader has stopped reading. Called
  /// once, outside the lock, on the pushing thread.
  virtual void on_stalled() {}

 protected:
  ~OutboxTarget() = default;
};

class Outbox {
 public:
  /// `max_frames` 0: unbounded. `overflow_message` is the RESOURCE_EXHAUSTED text.
  Outbox(OutboxTarget& target, std::size_t max_frames = 0, std::string overflow_message = {});

  /// Queues a message carrying `counted_frames` frames that count toward the
  /// bound. Returns false if the stream is closing (the message is dropped);
  /// an overflow drops the queue and closes it with RESOURCE_EXHAUSTED.
  bool push(Message message, std::size_t counted_frames = 0);
  /// Finishes with `status` once every queued message is written.
  void close(const grpc::Status& status);
  /// Drops queued messages and finishes with `status` as soon as no write is in flight.
  void abort(const grpc::Status& status);
  /// The reactor's OnWriteDone.
  void on_write_done(bool ok);

  /// The status the stream is finishing with, once decided.
  std::optional<grpc::Status> final_status() const;
  /// Counted frames queued and not yet handed to gRPC (the one in flight excluded). Read
  /// without the lock (it is asked after every read and write of a producer's stream): a
  /// caller that must see the count a completion left orders itself after that completion
  /// (AnimateReactor's flow_mutex_ does).
  std::size_t queued_frames() const;

  /// From now on each message's time from push to its completed write goes to `latency`,
  /// and `queued` follows the messages waiting here (both the server's metrics).
  void measure(Histogram& latency, std::atomic<std::int64_t>& queued);

 private:
  void pump();

  OutboxTarget& target_;
  const std::size_t max_frames_;
  const std::string overflow_message_;
  mutable std::mutex mutex_;
  struct Queued {
    Message message;
    std::size_t counted_frames;
    std::chrono::steady_clock::time_point pushed;
  };
  void drop_queue_locked();

  std::deque<Queued> queue_;
  std::atomic<std::size_t> queued_frames_{0};  // written under mutex_ only
  Message in_flight_;
  std::chrono::steady_clock::time_point in_flight_pushed_;
  Histogram* latency_ = nullptr;
  std::atomic<std::int64_t>* queued_ = nullptr;
  bool writing_ = false;
  bool finish_called_ = false;
  std::optional<grpc::Status> finish_status_;
};

}  // namespace lipsync::server
