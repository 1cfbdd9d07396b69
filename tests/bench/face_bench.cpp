// Simulated frames per second of the physics face on one core, per subdivision level.
//
// face_frame: the way the server and the exporters drive the solver: one FaceSolver::step per
// frame of a real track (a synthetic ARPAbet utterance of 100 phonemes rendered at 30 frames/s,
// closure and short-segment key frames included), dt = the time since the previous frame. A frame
// on the 30 frames/s grid is one 1/30 s substep; a key frame splits an interval into two shorter
// substeps, and a closure longer than 1/30 s takes several. Goal: level 1 at no more than 2 ms per
// frame, i.e. a real-time factor of at least 15 (the 33 ms of a frame in 2 ms). `realtime_x` is
// simulated seconds per CPU second over the whole track.
//
// face_step: one substep of the default 1/30 s (5 local–global iterations) with speech-like
// channel values that change every step, for comparison with older per-step figures.
//
// face_frame_iterations/LEVEL/K: face_frame with K local–global iterations instead of 5, for the
// cost side of fewer iterations at equal error (docs/performance.md, "The physics face's speed").
//
// face_frame_fast/LEVEL: face_frame with fast_face_solver_params() (two iterations from the
// targets' shift), the solver of a mesh stream that asks for the fast solve.
//
// With --benchmark_repetitions the minimum over repetitions is reported too (the least disturbed
// figure on a shared machine). Run pinned to one core:
//   taskset -c 1 face_bench --benchmark_repetitions=10
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/face/face_solver.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/synthetic.hpp"

namespace {

using namespace lipsync::face;

const lipsync::Track& utterance_track() {
  static const lipsync::Track track = [] {
    const auto& model = lipsync::ArticulationModel::builtin();
    const lipsync::PhoneSet arpabet = *lipsync::PhoneSet::builtin("arpabet", model);
    const auto segments = lipsync::build_segments(
        {"synthetic", "", lipsync::synthesize_utterance({.phonemes = 100, .seed = 2002})}, model, arpabet);
    return lipsync::render_track(model, segments, {.fps = 30});
  }();
  return track;
}

void step_frames(benchmark::State& state, const FaceSolverParams& params) {
  const FaceMesh mesh = build_face_mesh(FaceAsset::builtin(), static_cast<int>(state.range(0)));
  FaceSolver solver(mesh, FaceRig::builtin(), params);
  const lipsync::Track& track = utterance_track();
  std::size_t frame = 0;
  std::int64_t previous_us = 0, simulated_us = 0;
  for (auto _ : state) {
    if (frame == track.frame_count()) {
      state.PauseTiming();
      solver.reset();
      frame = 0;
      previous_us = 0;
      state.ResumeTiming();
    }
    const std::int64_t t_us = track.t_us[frame];
    solver.step(track.frame_values(frame), static_cast<double>(t_us - previous_us) * 1e-6);
    simulated_us += t_us - previous_us;
    previous_us = t_us;
    ++frame;
    benchmark::DoNotOptimize(solver.positions().data());
  }
  state.counters["soft_nodes"] = mesh.soft_node_count;
  state.counters["frames_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["realtime_x"] =
      benchmark::Counter(static_cast<double>(simulated_us) * 1e-6, benchmark::Counter::kIsRate);
  state.counters["track_frames"] = static_cast<double>(track.frame_count());
}

void face_frame(benchmark::State& state) {
  FaceSolverParams params;
  if (state.range(1) > 0) params.iterations = static_cast<int>(state.range(1));
  step_frames(state, params);
}

void face_frame_fast(benchmark::State& state) { step_frames(state, fast_face_solver_params()); }

void face_step(benchmark::State& state) {
  const FaceMesh mesh = build_face_mesh(FaceAsset::builtin(), static_cast<int>(state.range(0)));
  FaceSolver solver(mesh, FaceRig::builtin());
  const auto& model = lipsync::ArticulationModel::builtin();
  std::vector<float> channels(model.channel_count(), 0.0F);
  const double h = FaceSolverParams{}.time_step_s;
  int step = 0;
  for (auto _ : state) {
    const double t = step++ * h;
    for (std::size_t c = 0; c < channels.size(); ++c)
      channels[c] = static_cast<float>(0.5 + 0.5 * std::sin(2.0 * M_PI * (1.3 + 0.37 * static_cast<double>(c)) * t));
    solver.step(channels, h);
    benchmark::DoNotOptimize(solver.positions().data());
  }
  state.counters["soft_nodes"] = mesh.soft_node_count;
  state.counters["springs"] = static_cast<double>(solver.spring_count());
  state.counters["steps_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

const auto kMin = [](const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); };
BENCHMARK(face_frame)
    ->Args({0, 0})
    ->Args({1, 0})
    ->Args({2, 0})
    ->Unit(benchmark::kMillisecond)
    ->ComputeStatistics("min", kMin);
BENCHMARK(face_frame)
    ->Name("face_frame_iterations")
    ->Args({1, 1})
    ->Args({1, 2})
    ->Args({1, 3})
    ->Args({1, 4})
    ->Unit(benchmark::kMillisecond)
    ->ComputeStatistics("min", kMin);
BENCHMARK(face_frame_fast)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->ComputeStatistics("min", kMin);
BENCHMARK(face_step)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->ComputeStatistics("min", kMin);

}  // namespace

BENCHMARK_MAIN();
