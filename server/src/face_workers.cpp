#include "face_workers.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace lipsync::server {

FaceWorkers::FaceWorkers(std::size_t threads, Priority priority) {
  for (std::size_t i = 0; i < threads; ++i) threads_.emplace_back([this, priority] { run(priority); });
}

FaceWorkers::~FaceWorkers() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (std::thread& thread : threads_) thread.join();
}

void FaceWorkers::post(std::function<void()> job) {
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back(std::move(job));
  }
  wake_.notify_one();
}

void FaceWorkers::run(Priority priority) {
  // Both are per thread on Linux (PRIO_PROCESS with a thread id sets that
  // thread's nice). A failure leaves the thread at normal priority, which is
  // still correct, only less kind to the channel streams.
  if (priority == Priority::idle) {
    const sched_param param{};
    pthread_setschedparam(pthread_self(), SCHED_IDLE, &param);
  } else if (priority == Priority::low) {
    setpriority(PRIO_PROCESS, static_cast<id_t>(::syscall(SYS_gettid)), 10);
  }
  for (;;) {
    std::function<void()> job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stopping_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // stopping, and nothing left
      job = std::move(jobs_.front());
      jobs_.pop_front();
    }
    job();
  }
}

void FaceLane::post(std::function<void()> job) {
  bool schedule = false;
  {
    std::lock_guard lock(mutex_);
    jobs_.push_back(std::move(job));
    schedule = !scheduled_;
    scheduled_ = true;
  }
  if (schedule) workers_.post([this] { run_next(); });
}

void FaceLane::retire(std::function<void()> last) {
  {
    std::lock_guard lock(mutex_);
    if (scheduled_) {
      last_ = std::move(last);
      return;
    }
  }
  last();
}

void FaceLane::run_next() {
  std::function<void()> job;
  {
    std::lock_guard lock(mutex_);
    job = std::move(jobs_.front());
    jobs_.pop_front();
  }
  job();
  std::function<void()> last;
  {
    std::lock_guard lock(mutex_);
    if (!jobs_.empty()) {
      // One job per turn: the lane goes to the back of the pool's queue, so
      // lanes share the threads fairly.
      workers_.post([this] { run_next(); });
      return;
    }
    scheduled_ = false;
    last = std::move(last_);
  }
  if (last) last();  // may destroy the lane: nothing of `this` is touched after it
}

}  // namespace lipsync::server
