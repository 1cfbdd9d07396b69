// The report of `lipsync loadtest` (loadtest_report.hpp).
#include "loadtest_report.hpp"

#include <cstdio>
#include <nlohmann/json.hpp>
#include <utility>

namespace lipsync::cli {

void Totals::add(Totals&& other) {
  producers += other.producers;
  utterances_started += other.utterances_started;
  utterances_complete += other.utterances_complete;
  producer_frames += other.producer_frames;
  subscriber_frames += other.subscriber_frames;
  producer_batches += other.producer_batches;
  subscriber_batches += other.subscriber_batches;
  subscriptions += other.subscriptions;
  subscriptions_complete += other.subscriptions_complete;
  missing_frames += other.missing_frames;
  unexpected_frames += other.unexpected_frames;
  frames_without_positions += other.frames_without_positions;
  producer_latencies_us.insert(producer_latencies_us.end(), other.producer_latencies_us.begin(),
                               other.producer_latencies_us.end());
  subscriber_latencies_us.insert(subscriber_latencies_us.end(), other.subscriber_latencies_us.begin(),
                                 other.subscriber_latencies_us.end());
}

Summary summarise(Results results, double seconds, double generator_cpu) {
  Summary summary;
  summary.seconds = seconds;
  summary.generator_cpu = generator_cpu;
  for (std::size_t m = 0; m < 2; ++m) {
    summary.producer_latency_by_mesh[m] = percentiles(results.by_mesh[m].producer_latencies_us);
    summary.subscriber_latency_by_mesh[m] = percentiles(results.by_mesh[m].subscriber_latencies_us);
  }
  summary.groups = {results.by_mesh[0], results.by_mesh[1]};
  Totals& totals = summary.totals;
  totals.add(std::move(results.by_mesh[0]));
  totals.add(std::move(results.by_mesh[1]));
  summary.producer_latency = percentiles(totals.producer_latencies_us);
  summary.subscriber_latency = percentiles(totals.subscriber_latencies_us);
  std::uint64_t error_count = 0;
  for (const auto& [code, count] : results.errors) error_count += count;
  summary.every_frame = totals.missing_frames == 0 && totals.unexpected_frames == 0 &&
                        totals.frames_without_positions == 0 && error_count == 0 &&
                        totals.utterances_complete == totals.utterances_started &&
                        totals.subscriptions_complete == totals.subscriptions;
  summary.errors = std::move(results.errors);
  return summary;
}

namespace {

std::string encoding_name(const MeshRequest& mesh) {
  return mesh.encoding == client::v1::MESH_ENCODING_INT16 ? "int16" : "float32";
}

}  // namespace

void write_json_report(const LoadTestConfig& config, const std::string& address, const std::string& client_name,
                       const Summary& summary, std::ostream& out) {
  const auto group_json = [&](std::size_t m) {
    const Totals& group = summary.groups[m];
    nlohmann::json frames = {{"producers", group.producer_frames},
                             {"subscribers", group.subscriber_frames},
                             {"per_second", summary.frames_per_second(group)},
                             {"missing", group.missing_frames},
                             {"unexpected", group.unexpected_frames}};
    if (m == 1) frames["without_positions"] = group.frames_without_positions;
    return nlohmann::json{
        {"producers", group.producers},
        {"utterances", {{"started", group.utterances_started}, {"complete", group.utterances_complete}}},
        {"subscriptions", {{"started", group.subscriptions}, {"complete", group.subscriptions_complete}}},
        {"frames", frames},
        {"batches", {{"producers", group.producer_batches}, {"subscribers", group.subscriber_batches}}},
        {"latency_ms",
         {{"producers", to_json(summary.producer_latency_by_mesh[m])},
          {"subscribers", to_json(summary.subscriber_latency_by_mesh[m])}}},
    };
  };
  const Totals& totals = summary.totals;
  nlohmann::json report = {
      {"server", address},
      {"mode", config.realtime ? "realtime" : "fast"},
      {"client", client_name},
      {"producers", config.producers},
      {"subscribers_per_session", config.subscribers},
      {"duration_s", config.duration.count()},
      {"elapsed_s", summary.seconds},
      {"phonemes_per_utterance", config.phonemes},
      {"seed", config.seed},
      {"mesh",
       {{"share", config.mesh.share},
        {"subdivision", config.mesh.subdivision},
        {"encoding", encoding_name(config.mesh)},
        {"solve", config.mesh.solve == client::v1::MESH_SOLVE_FAST ? "fast" : "full"}}},
      {"utterances", {{"started", totals.utterances_started}, {"complete", totals.utterances_complete}}},
      {"subscriptions", {{"started", totals.subscriptions}, {"complete", totals.subscriptions_complete}}},
      {"frames",
       {{"producers", totals.producer_frames},
        {"subscribers", totals.subscriber_frames},
        {"per_second", summary.frames_per_second(totals)},
        {"missing", totals.missing_frames},
        {"unexpected", totals.unexpected_frames},
        {"without_positions", totals.frames_without_positions}}},
      {"batches", {{"producers", totals.producer_batches}, {"subscribers", totals.subscriber_batches}}},
      {"latency_ms",
       {{"producers", to_json(summary.producer_latency)}, {"subscribers", to_json(summary.subscriber_latency)}}},
      {"by_output", {{"mesh", group_json(1)}, {"no_mesh", group_json(0)}}},
      {"errors", summary.errors},
      {"verified", config.verify},
      {"generator_cpu_cores", summary.generator_cpu},
      {"every_frame_arrived", summary.every_frame},
  };
  out << report.dump(2) << '\n';
}

void write_text_report(const LoadTestConfig& config, const std::string& client_name, const Summary& summary,
                       std::ostream& out) {
  const Totals& totals = summary.totals;
  const std::array<Totals, 2>& groups = summary.groups;
  char line[256];
  std::snprintf(line, sizeof line,
                "loadtest: %d producers (%s), %d subscribers per session, %.1f s, seed %llu, client %s\n",
                config.producers, config.realtime ? "real time" : "fast", config.subscribers, summary.seconds,
                static_cast<unsigned long long>(config.seed), client_name.c_str());
  out << line;
  if (groups[1].producers > 0) {
    std::snprintf(line, sizeof line, "mesh: %d of %d producers (share %.2f), subdivision %u, %s, %s solve\n",
                  groups[1].producers, config.producers, config.mesh.share, config.mesh.subdivision,
                  encoding_name(config.mesh).c_str(),
                  config.mesh.solve == client::v1::MESH_SOLVE_FAST ? "fast" : "full");
    out << line;
  }
  out << "utterances: " << totals.utterances_started << " started, " << totals.utterances_complete
      << " complete; subscriptions: " << totals.subscriptions << " started, " << totals.subscriptions_complete
      << " complete\n";
  std::snprintf(line, sizeof line,
                "frames: %llu to producers (%llu batches), %llu to subscribers (%llu batches), %.0f/s; %llu missing, "
                "%llu unexpected\n",
                static_cast<unsigned long long>(totals.producer_frames),
                static_cast<unsigned long long>(totals.producer_batches),
                static_cast<unsigned long long>(totals.subscriber_frames),
                static_cast<unsigned long long>(totals.subscriber_batches), summary.frames_per_second(totals),
                static_cast<unsigned long long>(totals.missing_frames),
                static_cast<unsigned long long>(totals.unexpected_frames));
  out << line;
  if (groups[1].producers == 0) {
    out << "latency, computable to arrival (producers): " << to_text(summary.producer_latency) << '\n';
    if (config.subscribers > 0) {
      out << "latency, computable to arrival (subscribers): " << to_text(summary.subscriber_latency) << '\n';
    }
  } else {
    for (const std::size_t m : {std::size_t{0}, std::size_t{1}}) {
      const Totals& group = groups[m];
      const char* name = m == 1 ? "mesh" : "no mesh";
      std::snprintf(line, sizeof line,
                    "%s: %d producers, %llu utterances complete, frames %llu to producers, %llu to subscribers, %.0f/s",
                    name, group.producers, static_cast<unsigned long long>(group.utterances_complete),
                    static_cast<unsigned long long>(group.producer_frames),
                    static_cast<unsigned long long>(group.subscriber_frames), summary.frames_per_second(group));
      out << line;
      if (m == 1) out << "; " << group.frames_without_positions << " without positions";
      out << '\n';
      if (group.producers == 0) continue;
      out << "  latency, computable to arrival (" << name
          << " producers): " << to_text(summary.producer_latency_by_mesh[m]) << '\n';
      if (config.subscribers > 0) {
        out << "  latency, computable to arrival (" << name
            << " subscribers): " << to_text(summary.subscriber_latency_by_mesh[m]) << '\n';
      }
    }
  }
  std::snprintf(line, sizeof line, "load generator CPU: %.2f cores\n", summary.generator_cpu);
  out << line;
  out << "errors:";
  if (summary.errors.empty()) out << " none";
  for (const auto& [code, count] : summary.errors) out << ' ' << code << ' ' << count;
  out << '\n';
  if (!config.verify) {
    out << (summary.every_frame ? "result: no errors (frames not checked: --no-verify)\n"
                                : "result: FAILED (errors)\n");
  } else {
    out << (summary.every_frame ? "result: every frame arrived\n" : "result: FAILED (errors or missing frames)\n");
  }
}

}  // namespace lipsync::cli
