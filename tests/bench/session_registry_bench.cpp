// The cost of the session registry's lookups (SessionRegistry::find, which
// every Subscribe makes, and open, which every Animate with a session makes)
// as the number of ended sessions it retains grows. A load test at 1,000
// producers with subscribers holds ~4,000: each utterance opens a session, and
// finished ones are kept for --session-retention-ms (10 s by default).
//
//   build/tests/bench/session_registry_bench
//
// Each lookup also sweeps (forgets sessions whose retention has passed); the
// sweep's cost should depend on what it forgets, not on what is held.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>

#include "sessions/session.hpp"

namespace lipsync::server {
namespace {

/// A registry holding `ended` finished sessions (retention one hour) and one live one.
SessionRegistry& registry_with(std::size_t ended) {
  static std::map<std::size_t, std::unique_ptr<SessionRegistry>> made;
  auto& registry = made[ended];
  if (registry) return *registry;
  registry = std::make_unique<SessionRegistry>(ended + 10, 64, std::chrono::hours(1));
  const Message header = make_message(v1::TrackMessage{});
  const Message summary = make_message(v1::TrackMessage{});
  for (std::size_t i = 0; i < ended; ++i) {
    std::shared_ptr<Session> session;
    if (!registry->open("ended-" + std::to_string(i), header, session).ok()) std::abort();
    session->finish(summary);
  }
  std::shared_ptr<Session> live;  // the registry holds it; it stays live, never finished
  if (!registry->open("live", header, live).ok()) std::abort();
  return *registry;
}

void BM_FindALiveSession(benchmark::State& state) {
  SessionRegistry& registry = registry_with(static_cast<std::size_t>(state.range(0)));
  for (auto _ : state) benchmark::DoNotOptimize(registry.find("live"));
}
BENCHMARK(BM_FindALiveSession)->Arg(10)->Arg(1000)->Arg(4000)->Arg(10000);

}  // namespace
}  // namespace lipsync::server

BENCHMARK_MAIN();
