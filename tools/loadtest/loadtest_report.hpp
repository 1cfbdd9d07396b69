// The report of `lipsync loadtest` (loadtest_command.cpp runs the load; this is what it says of the
// run): the totals the run counted for the producers without and with the mesh and their
// subscribers, summed up with their latency percentiles and the verdict (every frame arrived, no
// errors), printed as a few lines for a person or, with --json, as one JSON document (tools/perf
// reads it).
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <ostream>
#include <string>
#include <vector>

#include "lipsync/client/animation_client.hpp"
#include "loadtest_shared.hpp"

namespace lipsync::cli {

/// The physics face asked of a share of the producers (--mesh-share, --mesh-subdivision, --mesh-encoding,
/// --mesh-solve).
struct MeshRequest {
  double share = 0.0;  ///< fraction of the producers
  std::uint32_t subdivision = 1;
  client::v1::MeshEncoding encoding = client::v1::MESH_ENCODING_FLOAT32;
  client::v1::MeshSolve solve = client::v1::MESH_SOLVE_FULL;
};

/// The run's shape, as the command line asked for it: the engine runs it, the report names it.
struct LoadTestConfig {
  int producers = 10;
  int subscribers = 0;
  std::chrono::seconds duration{10};
  bool realtime = true;
  std::size_t phonemes = 30;
  std::uint64_t seed = 1;
  bool verify = true;
  MeshRequest mesh;
};

/// What the producers of one kind (with or without the mesh) and their subscribers got.
struct Totals {
  int producers = 0;
  std::uint64_t utterances_started = 0;
  std::uint64_t utterances_complete = 0;
  std::uint64_t producer_frames = 0;
  std::uint64_t subscriber_frames = 0;
  std::uint64_t producer_batches = 0;
  std::uint64_t subscriber_batches = 0;
  std::uint64_t subscriptions = 0;
  std::uint64_t subscriptions_complete = 0;
  std::uint64_t missing_frames = 0;
  std::uint64_t unexpected_frames = 0;
  std::uint64_t frames_without_positions = 0;  ///< mesh producers only
  std::vector<std::int32_t> producer_latencies_us;
  std::vector<std::int32_t> subscriber_latencies_us;

  void add(Totals&& other);
};

/// Totals of the producers without the mesh ([0]) and with it ([1]), and the errors of all.
struct Results {
  std::array<Totals, 2> by_mesh;
  std::map<std::string, std::uint64_t> errors;
};

/// A finished run summed up: totals of all producers and of each kind, their latencies, and the verdict.
struct Summary {
  double seconds = 0;
  double generator_cpu = 0;      ///< cores the generator kept busy on average (its threads and gRPC's)
  std::array<Totals, 2> groups;  ///< without ([0]) and with ([1]) the mesh
  Totals totals;
  std::array<Percentiles, 2> producer_latency_by_mesh;
  std::array<Percentiles, 2> subscriber_latency_by_mesh;
  Percentiles producer_latency;
  Percentiles subscriber_latency;
  std::map<std::string, std::uint64_t> errors;
  bool every_frame = false;

  double frames_per_second(const Totals& group) const {
    return static_cast<double>(group.producer_frames + group.subscriber_frames) / seconds;
  }
};

/// `results` summed up over a run of `seconds` in which the generator kept `generator_cpu` cores busy.
Summary summarise(Results results, double seconds, double generator_cpu);

/// `--json`: the whole report as one JSON document (tools/perf reads it). `address` is the server's,
/// `client_name` the client that carried the calls (h2 or grpc).
void write_json_report(const LoadTestConfig& config, const std::string& address, const std::string& client_name,
                       const Summary& summary, std::ostream& out);

/// Without `--json`: a few lines for a person, the verdict last.
void write_text_report(const LoadTestConfig& config, const std::string& client_name, const Summary& summary,
                       std::ostream& out);

}  // namespace lipsync::cli
