// Face capacity: how much mesh work the server takes on, so that an admitted
// mesh stream keeps real time instead of starving.
//
// The face threads run at a low priority (face_workers.hpp): when the CPU is
// short they wait, which keeps the channel-only streams' latency but, with no
// limit, lets an admitted mesh stream fall ever further behind (a mesh Render
// once hit a 30 s deadline). So mesh work is admitted up to a capacity and
// refused beyond it with RESOURCE_EXHAUSTED naming the limit.
//
// Streams differ in cost: a face frame costs about 0.13, 0.63 and 3.1 ms at
// subdivision 0, 1 and 2 (docs/performance.md, "Face"), and a stream needs fps
// of them per second. Each stream therefore weighs its CPU need in units of a
// level-1, 30 fps stream (0.63 ms × 30 = 19 ms of CPU per second of speech):
// level 0 at 30 fps weighs 0.21, level 2 at 30 fps 4.9, level 1 at 60 fps 2.
// The fast solve (settings.outputs.mesh.solve = FAST) costs about 0.45, 0.45
// and 0.41 of that at levels 0, 1 and 2, and weighs so (level 1: 0.45).
// The capacity is --max-mesh-streams-per-face-thread such units per face
// thread (default 16: about a third of each face thread's core, which leaves
// the rest to the channel-only sessions; measured beside 1,000 of them in
// docs/performance.md, "With the physics face on").
//
// An admitted stream that still falls behind (the machine busier than the
// capacity assumes) fails fast: see FaceDeadline.
#pragma once

#include <grpcpp/support/status.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

#include "lipsync/v1/lipsync.pb.h"

namespace lipsync::server {

class FaceCapacity {
 public:
  /// `streams_per_thread` level-1 30 fps streams per face thread, `threads` face threads.
  FaceCapacity(std::size_t streams_per_thread, std::size_t threads);

  /// What a mesh stream at `subdivision` and `fps` with `solve` (FULL or FAST) weighs, in
  /// thousandths of a level-1, 30 fps FULL stream.
  static std::int64_t weight_milli(int subdivision, int fps, v1::MeshSolve solve = v1::MESH_SOLVE_FULL);

  /// Counts a mesh stream in, or RESOURCE_EXHAUSTED naming the capacity and the flag.
  grpc::Status admit(std::int64_t weight_milli);
  void release(std::int64_t weight_milli) { used_milli_ -= weight_milli; }

  /// Level-1 30 fps stream units in use and the capacity, thousandths.
  std::int64_t used_milli() const { return used_milli_.load(); }
  std::int64_t capacity_milli() const { return capacity_milli_; }

 private:
  const std::size_t streams_per_thread_;
  const std::size_t threads_;
  const std::int64_t capacity_milli_;
  std::atomic<std::int64_t> used_milli_{0};
};

/// The bound on how far an admitted mesh stream may fall behind real time. A
/// frame is due when it was released or when its utterance time comes on the
/// stream's clock (started at the stream's start), whichever is later; a frame
/// the face reaches more than `max_lag` after it was due ends the stream with
/// DEADLINE_EXCEEDED, so the client learns at once instead of waiting.
class FaceDeadline {
 public:
  using Clock = std::chrono::steady_clock;

  FaceDeadline(Clock::time_point stream_start, std::chrono::milliseconds max_lag)
      : stream_start_(stream_start), max_lag_(max_lag) {}

  /// When a frame at utterance time `t_us`, released at `released`, is due.
  Clock::time_point due(std::int64_t t_us, Clock::time_point released) const;
  /// OK, or DEADLINE_EXCEEDED saying how far behind the face is, if `now` is more than max_lag past `due`.
  grpc::Status check(Clock::time_point due, Clock::time_point now) const;

 private:
  Clock::time_point stream_start_;
  std::chrono::milliseconds max_lag_;
};

}  // namespace lipsync::server
