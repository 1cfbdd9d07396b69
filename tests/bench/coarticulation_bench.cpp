// Frames per second of the coarticulation engine, windowed (Eq. 4–5, at most
// 15 segments per frame) against the unwindowed Cohen–Massaro reference
// (Eq. 1, every segment per frame), on synthetic ARPAbet speech of 10 to
// 10,000 segments with the built-in model, and the streaming engine with many
// streams taking turns, as in a loaded server. Both run in the same process, so
// their ratio is meaningful on a noisy machine; docs/performance.md has the
// method and the figures.
//
//   build/tests/bench/coarticulation_bench --benchmark_min_time=0.5
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <vector>

#include "lipsync/coarticulation.hpp"
#include "lipsync/keyframes.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/synthetic.hpp"

namespace lipsync {
namespace {

struct Utterance {
  std::vector<Segment> segments;
  std::vector<ScheduledFrame> frames;
};

const Utterance& utterance(std::size_t phonemes) {
  static std::map<std::size_t, Utterance> cache;
  auto it = cache.find(phonemes);
  if (it != cache.end()) return it->second;
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  Utterance u;
  u.segments =
      build_segments({"synthetic", "", synthesize_utterance({.phonemes = phonemes, .seed = 2002})}, model, arpabet);
  FrameScheduler scheduler(model, {.fps = 30});
  for (std::size_t i = 0; i < u.segments.size(); ++i) scheduler.add_segment(u.segments[i], i, u.frames);
  scheduler.finish(u.frames);
  return cache.emplace(phonemes, std::move(u)).first->second;
}

/// Whole offline render (scheduling and evaluation) of the utterance.
void BM_Windowed_RenderTrack(benchmark::State& state) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const Utterance& u = utterance(static_cast<std::size_t>(state.range(0)));
  std::size_t frames = 0;
  for (auto _ : state) {
    Track track = render_track(model, u.segments, {.fps = 30});
    frames += track.frame_count();
    benchmark::DoNotOptimize(track.values.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(frames));
  state.counters["segments"] = static_cast<double>(u.segments.size());
}

/// The streaming engine fed one segment at a time, frames shipped as they come.
void BM_Windowed_Streaming(benchmark::State& state) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const Utterance& u = utterance(static_cast<std::size_t>(state.range(0)));
  std::size_t frames = 0;
  Track track;
  track.channel_count = model.channel_count();
  for (auto _ : state) {
    StreamingRenderer renderer(model, {.fps = 30});
    for (const Segment& segment : u.segments) {
      renderer.push(segment, track);
      frames += track.frame_count();
      track.clear();
    }
    renderer.finish(track);
    frames += track.frame_count();
    track.clear();
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(frames));
}

/// The streaming engine as a server at load runs it: `range(0)` streams, each
/// fed the same 30-phoneme utterance one segment at a time, in turn (stream 1
/// gets a segment, then stream 2, ...), so that between two segments of one
/// stream the others pass through the caches as thousands of real-time
/// sessions do. With one stream it is BM_Windowed_Streaming on a short
/// utterance; N streams against one show what fetching each stream's own
/// memory costs.
void BM_Streaming_Interleaved(benchmark::State& state) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const Utterance& u = utterance(30);
  const auto streams = static_cast<std::size_t>(state.range(0));
  // One set of tables for all streams, as the server builds it once per model.
  const auto tables = std::make_shared<const CoarticulationTables>(model);
  std::vector<std::unique_ptr<StreamingRenderer>> renderers;
  std::vector<Track> tracks(streams);
  for (Track& track : tracks) track.channel_count = model.channel_count();
  std::size_t frames = 0;
  for (auto _ : state) {
    renderers.clear();
    for (std::size_t s = 0; s < streams; ++s) {
      renderers.push_back(std::make_unique<StreamingRenderer>(tables, RenderOptions{.fps = 30}));
    }
    for (const Segment& segment : u.segments) {
      for (std::size_t s = 0; s < streams; ++s) {
        renderers[s]->push(segment, tracks[s]);
        frames += tracks[s].frame_count();
        tracks[s].clear();
      }
    }
    for (std::size_t s = 0; s < streams; ++s) {
      renderers[s]->finish(tracks[s]);
      frames += tracks[s].frame_count();
      tracks[s].clear();
    }
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(frames));
}

/// The unwindowed reference on up to 300 frames spread over the utterance
/// (its cost per frame grows with the utterance, so whole renders of long
/// utterances would take minutes).
void BM_Unwindowed_Reference(benchmark::State& state) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const Utterance& u = utterance(static_cast<std::size_t>(state.range(0)));
  const std::size_t stride = std::max<std::size_t>(1, u.frames.size() / 300);
  std::vector<float> out(model.channel_count());
  std::size_t frames = 0;
  for (auto _ : state) {
    for (std::size_t f = 0; f < u.frames.size(); f += stride) {
      evaluate_unwindowed(model, u.segments, u.frames[f].t_us, out);
      benchmark::DoNotOptimize(out.data());
      ++frames;
    }
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(frames));
  state.counters["segments"] = static_cast<double>(u.segments.size());
}

BENCHMARK(BM_Windowed_RenderTrack)->Arg(10)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Windowed_Streaming)->Arg(10)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Streaming_Interleaved)->Arg(1)->Arg(100)->Arg(3000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Unwindowed_Reference)->Arg(10)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace lipsync

BENCHMARK_MAIN();
