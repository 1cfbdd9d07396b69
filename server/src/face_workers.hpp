// Where the physics face runs: a small pool of low-priority threads, off gRPC's
// callback threads.
//
// A mesh stream costs milliseconds per frame (FaceSolver steps) and about
// 0.1 s to set up (the factorisation), which a reaction must not spend: gRPC
// runs every stream's reactions on a couple of threads, so one face stream
// would stall all the others. Face work is posted here instead. The threads
// run at a lower scheduling priority (by default SCHED_IDLE: only on CPU time
// no other thread wants), so when the machine is short of CPU the channel-only
// streams keep their latency and the face streams slow down, not the other way
// round.
//
// A FaceLane runs one stream's jobs in the order they were posted, one at a
// time (frames must leave in order); different lanes share the threads, one
// job at a time each, round robin. `retire` runs a last function once the
// lane is idle: the reactor deletes itself through it, so no job outlives it.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace lipsync::server {

class FaceWorkers {
 public:
  /// idle: SCHED_IDLE (runs only when no other thread wants the CPU); low: nice 10; normal: as
  /// the rest of the server. Lowering a thread's priority needs no privilege.
  enum class Priority { idle, low, normal };

  /// `threads` ≥ 1 threads at `priority`.
  FaceWorkers(std::size_t threads, Priority priority);
  /// Runs what is still queued, then joins.
  ~FaceWorkers();
  FaceWorkers(const FaceWorkers&) = delete;
  FaceWorkers& operator=(const FaceWorkers&) = delete;

  void post(std::function<void()> job);

 private:
  void run(Priority priority);

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> jobs_;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

class FaceLane {
 public:
  explicit FaceLane(FaceWorkers& workers) : workers_(workers) {}
  FaceLane(const FaceLane&) = delete;
  FaceLane& operator=(const FaceLane&) = delete;

  /// Queues `job` behind the lane's earlier jobs.
  void post(std::function<void()> job);
  /// Runs `last` once every queued job has run (at once, on this thread, if the
  /// lane is idle). `last` may destroy the lane.
  void retire(std::function<void()> last);

 private:
  void run_next();

  FaceWorkers& workers_;
  std::mutex mutex_;
  std::deque<std::function<void()>> jobs_;
  bool scheduled_ = false;  // a run_next is posted or running
  std::function<void()> last_;
};

}  // namespace lipsync::server
