// The face's thread pool and lanes (face_workers.hpp). The priority is set by
// one job per thread, posted first: each waits until all of them have started,
// so every thread runs exactly one, and none runs face work before its own.
#include "face_workers.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <boost/asio/post.hpp>

namespace lipsync::server {
namespace {

/// Lowers the calling thread's scheduling priority. Both calls are per thread
/// on Linux (PRIO_PROCESS with a thread id sets that thread's nice). A failure
/// leaves the thread at normal priority, which is still correct, only less
/// kind to the channel streams.
void lower_this_thread(FaceWorkers::Priority priority) {
  if (priority == FaceWorkers::Priority::idle) {
    const sched_param param{};
    pthread_setschedparam(pthread_self(), SCHED_IDLE, &param);
  } else if (priority == FaceWorkers::Priority::low) {
    setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)), 10);
  }
}

}  // namespace

FaceWorkers::FaceWorkers(std::size_t threads, Priority priority)
    : prioritised_(static_cast<std::ptrdiff_t>(threads)), pool_(threads) {
  for (std::size_t i = 0; i < threads; ++i) {
    boost::asio::post(pool_, [this, priority] {
      {
        std::lock_guard lock(thread_ids_mutex_);
        thread_ids_.push_back(static_cast<pid_t>(::syscall(SYS_gettid)));
      }
      lower_this_thread(priority);
      prioritised_.arrive_and_wait();
    });
  }
  prioritised_.wait();
}

FaceWorkers::~FaceWorkers() { pool_.join(); }

bool FaceWorkers::restore_normal_priority() {
  std::lock_guard lock(thread_ids_mutex_);
  bool restored = true;
  for (const pid_t thread : thread_ids_) {
    const sched_param param{};
    restored = ::sched_setscheduler(thread, SCHED_OTHER, &param) == 0 && restored;
    restored = ::setpriority(PRIO_PROCESS, static_cast<id_t>(thread), 0) == 0 && restored;
  }
  return restored;
}

void FaceWorkers::post(std::function<void()> job) { boost::asio::post(pool_, std::move(job)); }

void FaceLane::post(std::function<void()> job) { boost::asio::post(strand_, std::move(job)); }

}  // namespace lipsync::server
