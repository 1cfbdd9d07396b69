// Where the physics face runs: a Boost.Asio thread_pool of low-priority
// threads, off gRPC's callback threads.
//
// A mesh stream costs milliseconds per frame (FaceSolver steps) and about
// 0.1 s to set up (the factorisation), which a reaction must not spend: gRPC
// runs every stream's reactions on a couple of threads, so one face stream
// would stall all the others. Face work is posted here instead. The threads
// run at a lower scheduling priority (by default SCHED_IDLE: only on CPU time
// no other thread wants), so when the machine is short of CPU the channel-only
// streams keep their latency and the face streams slow down, not the other way
// round. Each pool thread lowers its own priority first thing, before it runs
// any job.
//
// A thread at SCHED_IDLE needs CPU time to end as much as to work: on a busy
// machine the process could not exit (the kernel waits for every thread to die)
// for seconds after a mesh call had used the pool. So a shutdown gives the
// threads their normal priority back first (restore_normal_priority); that
// takes CAP_SYS_NICE or an RLIMIT_NICE of at least 20 (systemd: LimitNICE=+0),
// which lipsyncd raises its soft limit toward at start.
//
// A FaceLane is one stream's strand on the pool: its jobs run in the order
// they were posted, one at a time (frames must leave in order); different
// lanes run in parallel on the pool's threads. `retire` queues a last job
// behind the others: the reactor deletes itself through it, so no job
// outlives it.
#pragma once

#include <sys/types.h>

#include <boost/asio/strand.hpp>
#include <boost/asio/thread_pool.hpp>
#include <cstddef>
#include <functional>
#include <latch>
#include <mutex>
#include <vector>

namespace lipsync::server {

class FaceWorkers {
 public:
  /// idle: SCHED_IDLE (runs only when no other thread wants the CPU); low: nice 10; normal: as
  /// the rest of the server. Lowering a thread's priority needs no privilege.
  enum class Priority { idle, low, normal };

  /// `threads` ≥ 1 threads at `priority` (set on every thread before this returns).
  FaceWorkers(std::size_t threads, Priority priority);
  /// Runs what is still queued, then joins.
  ~FaceWorkers();
  FaceWorkers(const FaceWorkers&) = delete;
  FaceWorkers& operator=(const FaceWorkers&) = delete;

  /// Puts every thread back at the normal priority (SCHED_OTHER, nice 0), so that a shutdown
  /// never waits for CPU time no other thread wants. False if the system does not allow it.
  bool restore_normal_priority();

  /// Runs `job` on one of the threads.
  void post(std::function<void()> job);
  boost::asio::thread_pool::executor_type executor() { return pool_.get_executor(); }

 private:
  std::latch prioritised_;  // before pool_: outlives the threads' first jobs
  std::mutex thread_ids_mutex_;
  std::vector<pid_t> thread_ids_;  // the pool's threads (Linux thread ids)
  boost::asio::thread_pool pool_;
};

class FaceLane {
 public:
  explicit FaceLane(FaceWorkers& workers) : strand_(boost::asio::make_strand(workers.executor())) {}
  FaceLane(const FaceLane&) = delete;
  FaceLane& operator=(const FaceLane&) = delete;

  /// Queues `job` behind the lane's earlier jobs.
  void post(std::function<void()> job);
  /// Runs `last` on a face thread once every job queued before it has run.
  /// `last` may destroy the lane.
  void retire(std::function<void()> last) { post(std::move(last)); }

 private:
  boost::asio::strand<boost::asio::thread_pool::executor_type> strand_;
};

}  // namespace lipsync::server
