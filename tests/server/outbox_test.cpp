// The outgoing side of a stream (server/src/rpc/outbox.hpp), against a target that
// records what the outbox asks of gRPC: one write in flight at a time, in push
// order; Finish only once no write is outstanding, after every queued message
// for close and at once for abort; the bound and a failed write end the stream
// with the right status; and, with pushers and completions on several threads,
// every message is written exactly once and in each pusher's order.
#include "rpc/outbox.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

namespace lipsync::server {
namespace {

/// A message whose summary's frame count names it.
Message numbered(std::uint64_t number) {
  v1::TrackMessage message;
  message.mutable_summary()->set_frames(number);
  return make_message(std::move(message));
}

std::uint64_t number_of(const OutgoingMessage& message) { return message.message().summary().frames(); }

/// What the outbox asked of its target so far.
struct Record {
  std::vector<std::uint64_t> written;  // the messages whose writes started, in order
  int writes_in_flight = 0;
  int most_writes_in_flight = 0;
  int finishes = 0;
  int writes_at_finish = -1;  // writes in flight when Finish came
  int stalls = 0;
  std::optional<grpc::Status> finished_with;
};

/// Records start_write and finish as a reactor would pass them to gRPC; the test
/// completes each write by calling the outbox's on_write_done.
class RecordingTarget final : public OutboxTarget {
 public:
  void start_write(const OutgoingMessage& message) override {
    std::lock_guard lock(mutex_);
    ++record_.writes_in_flight;
    record_.most_writes_in_flight = std::max(record_.most_writes_in_flight, record_.writes_in_flight);
    record_.written.push_back(number_of(message));
    changed_.notify_all();
  }
  void finish(const grpc::Status& status) override {
    std::lock_guard lock(mutex_);
    ++record_.finishes;
    record_.finished_with = status;
    record_.writes_at_finish = record_.writes_in_flight;
    changed_.notify_all();
  }
  void on_stalled() override {
    std::lock_guard lock(mutex_);
    ++record_.stalls;
  }

  /// Marks the write in flight as done (before the outbox hears of it).
  void write_done() {
    std::lock_guard lock(mutex_);
    --record_.writes_in_flight;
  }
  /// Waits until `count` writes have started or Finish was called; false after 10 s.
  bool wait_for_writes(std::size_t count) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, std::chrono::seconds(10),
                             [&] { return record_.written.size() >= count || record_.finishes > 0; });
  }
  Record record() const {
    std::lock_guard lock(mutex_);
    return record_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  Record record_;
};

/// Completes the write in flight, as gRPC's OnWriteDone would.
void complete(RecordingTarget& target, Outbox& outbox, bool ok = true) {
  target.write_done();
  outbox.on_write_done(ok);
}

TEST(Outbox, WritesOneMessageAtATimeInPushOrder) {
  RecordingTarget target;
  Outbox outbox(target);
  for (std::uint64_t n = 1; n <= 3; ++n) EXPECT_TRUE(outbox.push(numbered(n)));
  EXPECT_EQ(target.record().written, (std::vector<std::uint64_t>{1}));
  complete(target, outbox);
  EXPECT_EQ(target.record().written, (std::vector<std::uint64_t>{1, 2}));
  complete(target, outbox);
  complete(target, outbox);
  EXPECT_EQ(target.record().written, (std::vector<std::uint64_t>{1, 2, 3}));
  EXPECT_EQ(target.record().most_writes_in_flight, 1);
  EXPECT_EQ(target.record().finishes, 0);
}

TEST(Outbox, CountsTheFramesWaitingButNotTheOneInFlight) {
  RecordingTarget target;
  Outbox outbox(target);
  outbox.push(numbered(1), 5);  // written at once
  EXPECT_EQ(outbox.queued_frames(), 0U);
  outbox.push(numbered(2), 7);
  outbox.push(numbered(3), 11);
  EXPECT_EQ(outbox.queued_frames(), 18U);
  complete(target, outbox);  // 2 goes out
  EXPECT_EQ(outbox.queued_frames(), 11U);
  complete(target, outbox);
  EXPECT_EQ(outbox.queued_frames(), 0U);
}

TEST(Outbox, CloseFinishesAfterEveryQueuedMessageIsWritten) {
  RecordingTarget target;
  Outbox outbox(target);
  outbox.push(numbered(1));
  outbox.push(numbered(2));
  outbox.close(grpc::Status::OK);
  EXPECT_FALSE(outbox.push(numbered(3))) << "a closing stream takes no more messages";
  complete(target, outbox);
  EXPECT_EQ(target.record().finishes, 0) << "message 2 is still to be written";
  complete(target, outbox);
  EXPECT_EQ(target.record().written, (std::vector<std::uint64_t>{1, 2}));
  EXPECT_EQ(target.record().finishes, 1);
  EXPECT_EQ(target.record().writes_at_finish, 0);
  EXPECT_TRUE(target.record().finished_with->ok());
}

TEST(Outbox, AbortDropsTheQueueAndFinishesOnceTheWriteInFlightIsDone) {
  RecordingTarget target;
  Outbox outbox(target);
  outbox.push(numbered(1));
  outbox.push(numbered(2));
  outbox.abort(grpc::Status(grpc::StatusCode::UNAVAILABLE, "shutting down"));
  EXPECT_EQ(target.record().finishes, 0) << "Finish must wait for the write in flight";
  EXPECT_EQ(outbox.queued_frames(), 0U);
  complete(target, outbox);
  EXPECT_EQ(target.record().written, (std::vector<std::uint64_t>{1}));
  ASSERT_EQ(target.record().finishes, 1);
  EXPECT_EQ(target.record().writes_at_finish, 0);
  EXPECT_EQ(target.record().finished_with->error_code(), grpc::StatusCode::UNAVAILABLE);
}

TEST(Outbox, OverflowingTheBoundEndsTheStreamWithResourceExhaustedAndItsMessage) {
  RecordingTarget target;
  Outbox outbox(target, 10, "the subscriber fell 10 frames behind");
  EXPECT_TRUE(outbox.push(numbered(1), 4));  // in flight: not counted
  EXPECT_TRUE(outbox.push(numbered(2), 6));
  EXPECT_TRUE(outbox.push(numbered(3), 4));  // 10 waiting: at the bound, not over it
  EXPECT_FALSE(outbox.push(numbered(4), 1));
  EXPECT_EQ(target.record().stalls, 1) << "a write was in flight when the bound overflowed";
  EXPECT_EQ(outbox.queued_frames(), 0U);
  complete(target, outbox);
  EXPECT_EQ(target.record().written, (std::vector<std::uint64_t>{1}));
  ASSERT_EQ(target.record().finishes, 1);
  EXPECT_EQ(target.record().finished_with->error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_EQ(target.record().finished_with->error_message(), "the subscriber fell 10 frames behind");
}

TEST(Outbox, AFailedWriteDropsTheQueueAndFinishesCancelled) {
  RecordingTarget target;
  Outbox outbox(target);
  outbox.push(numbered(1));
  outbox.push(numbered(2));
  complete(target, outbox, false);
  EXPECT_EQ(target.record().written, (std::vector<std::uint64_t>{1}));
  ASSERT_EQ(target.record().finishes, 1);
  EXPECT_EQ(target.record().finished_with->error_code(), grpc::StatusCode::CANCELLED);
  EXPECT_FALSE(outbox.push(numbered(3)));
}

TEST(Outbox, PushersOnSeveralThreadsGetEveryMessageWrittenOnceAndInTheirOrder) {
  // Four pushers (a producer's reactions, a session fanning out) and a completion
  // thread (gRPC's OnWriteDone), as in the server; then close.
  constexpr std::uint64_t kPushers = 4;
  constexpr std::uint64_t kPerPusher = 2'000;
  RecordingTarget target;
  Outbox outbox(target);
  std::thread completions([&] {
    for (std::size_t done = 0; done < kPushers * kPerPusher; ++done) {
      ASSERT_TRUE(target.wait_for_writes(done + 1)) << "write " << done + 1 << " never started";
      complete(target, outbox);
    }
  });
  std::vector<std::thread> pushers;
  for (std::uint64_t pusher = 0; pusher < kPushers; ++pusher) {
    pushers.emplace_back([&, pusher] {
      for (std::uint64_t k = 0; k < kPerPusher; ++k) outbox.push(numbered(pusher * kPerPusher + k), 1);
    });
  }
  for (auto& pusher : pushers) pusher.join();
  completions.join();
  outbox.close(grpc::Status::OK);

  const std::vector<std::uint64_t> written = target.record().written;
  ASSERT_EQ(written.size(), kPushers * kPerPusher);
  std::vector<std::uint64_t> next(kPushers, 0);  // each pusher's next expected number
  for (const std::uint64_t number : written) {
    const std::uint64_t pusher = number / kPerPusher;
    ASSERT_EQ(number % kPerPusher, next[pusher]) << "pusher " << pusher << "'s messages out of order";
    ++next[pusher];
  }
  EXPECT_EQ(target.record().most_writes_in_flight, 1);
  EXPECT_EQ(outbox.queued_frames(), 0U);
  EXPECT_EQ(target.record().finishes, 1);
}

}  // namespace
}  // namespace lipsync::server
