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
      lower_this_thread(priority);
      prioritised_.arrive_and_wait();
    });
  }
  prioritised_.wait();
}

FaceWorkers::~FaceWorkers() { pool_.join(); }

void FaceWorkers::post(std::function<void()> job) { boost::asio::post(pool_, std::move(job)); }

void FaceLane::post(std::function<void()> job) { boost::asio::post(strand_, std::move(job)); }

}  // namespace lipsync::server
