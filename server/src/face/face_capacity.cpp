// Mesh admission by CPU weight and the fail-fast bound (face_capacity.hpp).
#include "face_capacity.hpp"

#include <algorithm>
#include <array>
#include <cstdio>

namespace lipsync::server {
namespace {

// Median ms per face frame at subdivision 0, 1, 2 (tests/bench/face_bench,
// docs/performance.md "Face"), relative to level 1, in thousandths.
constexpr std::array<std::int64_t, 3> kFrameCostMilliOfLevel1 = {206, 1000, 4921};  // 0.13, 0.63, 3.1 ms
// The same for the fast solve: the level's weight times face_bench's face_frame_fast/LEVEL over
// face_frame/LEVEL/0, measured in pairs (0.45, 0.45, 0.41).
constexpr std::array<std::int64_t, 3> kFastFrameCostMilliOfLevel1 = {92, 446, 2032};
constexpr std::int64_t kReferenceFps = 30;

std::string units(std::int64_t milli) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f", static_cast<double>(milli) / 1000.0);
  return text;
}

}  // namespace

FaceCapacity::FaceCapacity(std::size_t streams_per_thread, std::size_t threads)
    : streams_per_thread_(streams_per_thread),
      threads_(threads),
      capacity_milli_(static_cast<std::int64_t>(streams_per_thread * threads) * 1000) {}

std::int64_t FaceCapacity::weight_milli(int subdivision, int fps, v1::MeshSolve solve) {
  const auto level = static_cast<std::size_t>(std::clamp(subdivision, 0, 2));
  const auto& cost = solve == v1::MESH_SOLVE_FAST ? kFastFrameCostMilliOfLevel1 : kFrameCostMilliOfLevel1;
  return std::max<std::int64_t>(1, cost[level] * fps / kReferenceFps);
}

grpc::Status FaceCapacity::admit(std::int64_t weight_milli) {
  std::int64_t used = used_milli_.load();
  while (true) {
    if (used + weight_milli > capacity_milli_) {
      return {grpc::StatusCode::RESOURCE_EXHAUSTED,
              "the face is at capacity: mesh streams in progress weigh " + units(used) + " and this one " +
                  units(weight_milli) + " level-1 30 fps streams, more than the " + units(capacity_milli_) +
                  " the server takes on (--max-mesh-streams-per-face-thread=" + std::to_string(streams_per_thread_) +
                  " x " + std::to_string(threads_) +
                  " face threads); retry later or ask for a lower subdivision or the FAST solve "
                  "(settings.outputs.mesh.solve)"};
    }
    if (used_milli_.compare_exchange_weak(used, used + weight_milli)) return grpc::Status::OK;
  }
}

FaceDeadline::Clock::time_point FaceDeadline::due(std::int64_t t_us, Clock::time_point released) const {
  return std::max(released, stream_start_ + std::chrono::microseconds(t_us));
}

grpc::Status FaceDeadline::check(Clock::time_point due, Clock::time_point now) const {
  const auto behind = std::chrono::duration_cast<std::chrono::milliseconds>(now - due);
  if (behind <= max_lag_) return grpc::Status::OK;
  return {grpc::StatusCode::DEADLINE_EXCEEDED,
          "the face fell " + std::to_string(behind.count()) + " ms behind real time, more than --mesh-max-lag-ms=" +
              std::to_string(max_lag_.count()) + ": the server is short of CPU for its mesh streams"};
}

}  // namespace lipsync::server
