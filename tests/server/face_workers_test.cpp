// The face threads (server/src/face/face_workers.hpp): a lane runs its jobs in
// order and one at a time while lanes run side by side, retire comes last, the
// destructor runs what is queued, and every thread has the asked priority.
#include "face/face_workers.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sched.h>
#include <sys/resource.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace lipsync::server {
namespace {

using namespace std::chrono_literals;

/// Each lane's jobs record their number; jobs sleep a little so that lanes overlap.
TEST(FaceLane, RunsItsJobsInOrderAndOneAtATimeWhileLanesShareTheThreads) {
  constexpr int kLanes = 6;
  constexpr int kJobs = 200;
  std::vector<std::vector<int>> seen(kLanes);
  std::vector<std::atomic<int>> running(kLanes);
  std::atomic<int> overlaps = 0;
  std::atomic<int> lanes_at_once = 0, most_lanes_at_once = 0;
  {
    FaceWorkers workers(4, FaceWorkers::Priority::normal);
    std::vector<std::unique_ptr<FaceLane>> lanes;
    for (int lane = 0; lane < kLanes; ++lane) lanes.push_back(std::make_unique<FaceLane>(workers));
    for (int job = 0; job < kJobs; ++job) {
      for (int lane = 0; lane < kLanes; ++lane) {
        lanes[static_cast<std::size_t>(lane)]->post([&, lane, job] {
          const auto index = static_cast<std::size_t>(lane);
          if (running[index]++ != 0) ++overlaps;
          const int now = ++lanes_at_once;
          int most = most_lanes_at_once.load();
          while (now > most && !most_lanes_at_once.compare_exchange_weak(most, now)) {
          }
          seen[index].push_back(job);  // only this lane's jobs touch it: no lock needed if they never overlap
          if (job % 50 == 0) std::this_thread::sleep_for(1ms);
          --lanes_at_once;
          --running[index];
        });
      }
    }
  }  // the destructor runs everything still queued
  std::vector<int> expected(kJobs);
  for (int job = 0; job < kJobs; ++job) expected[static_cast<std::size_t>(job)] = job;
  for (int lane = 0; lane < kLanes; ++lane) EXPECT_EQ(seen[static_cast<std::size_t>(lane)], expected) << lane;
  EXPECT_EQ(overlaps.load(), 0);
  EXPECT_GT(most_lanes_at_once.load(), 1);
}

TEST(FaceLane, RetireRunsAfterEveryJobQueuedBeforeItAndMayDestroyTheLane) {
  FaceWorkers workers(2, FaceWorkers::Priority::normal);
  std::mutex mutex;
  std::vector<int> order;
  std::atomic<bool> retired = false;
  auto* lane = new FaceLane(workers);
  for (int job = 0; job < 20; ++job) {
    lane->post([&, job] {
      std::this_thread::sleep_for(100us);
      std::lock_guard lock(mutex);
      order.push_back(job);
    });
  }
  lane->retire([&, lane] {
    {
      std::lock_guard lock(mutex);
      order.push_back(-1);
    }
    delete lane;
    retired = true;
  });
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!retired && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(1ms);
  ASSERT_TRUE(retired);
  std::lock_guard lock(mutex);
  ASSERT_EQ(order.size(), 21u);
  EXPECT_EQ(order.back(), -1);
}

/// The scheduling policy and nice value of a pool thread, seen from inside a job.
struct ThreadPriority {
  int policy;
  int nice;
  bool operator==(const ThreadPriority&) const = default;
};

/// One job per thread (each waits until all have started, so each is on its own thread).
std::vector<ThreadPriority> priorities_of(FaceWorkers::Priority priority, std::size_t threads) {
  std::mutex mutex;
  std::vector<ThreadPriority> seen;
  std::vector<std::thread::id> ids;
  std::atomic<std::size_t> started = 0;
  {
    FaceWorkers workers(threads, priority);
    for (std::size_t i = 0; i < threads; ++i) {
      workers.post([&] {
        ++started;
        const auto deadline = std::chrono::steady_clock::now() + 10s;
        while (started < threads && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
        const ThreadPriority mine{sched_getscheduler(0), getpriority(PRIO_PROCESS, 0)};
        std::lock_guard lock(mutex);
        seen.push_back(mine);
        ids.push_back(std::this_thread::get_id());
      });
    }
  }
  std::sort(ids.begin(), ids.end());
  EXPECT_EQ(std::unique(ids.begin(), ids.end()) - ids.begin(), static_cast<std::ptrdiff_t>(threads));
  return seen;
}

TEST(FaceWorkers, EveryThreadRunsAtTheAskedPriority) {
  const int normal_nice = getpriority(PRIO_PROCESS, 0);
  using ::testing::Each;
  EXPECT_THAT(priorities_of(FaceWorkers::Priority::idle, 3), Each(ThreadPriority{SCHED_IDLE, normal_nice}));
  EXPECT_THAT(priorities_of(FaceWorkers::Priority::low, 3),
              Each(ThreadPriority{SCHED_OTHER, std::max(normal_nice, 10)}));
  EXPECT_THAT(priorities_of(FaceWorkers::Priority::normal, 3), Each(ThreadPriority{SCHED_OTHER, normal_nice}));
}

}  // namespace
}  // namespace lipsync::server
