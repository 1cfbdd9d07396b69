// What both modes of the load generator share: the server's address (on this machine only),
// latency percentiles, and the generator's own CPU (so that a run whose generator was saturated
// can be told apart from one that measured the server).
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "arguments.hpp"

namespace lipsync::cli {

/// --server, which must be a loopback address; UsageError otherwise.
std::string loopback_server_address(const Arguments& arguments);

/// Latency percentiles, ms.
struct Percentiles {
  double p50_ms = 0, p95_ms = 0, p99_ms = 0, max_ms = 0;
};

/// The percentiles of `values_us` (sorted in place); all 0 when it is empty.
Percentiles percentiles(std::vector<std::int32_t>& values_us);
nlohmann::json to_json(const Percentiles& p);
/// "p50 1.23 ms  p95 ...  p99 ...  max ...".
std::string to_text(const Percentiles& p);

/// CPU time this process has used (user + system), seconds.
double process_cpu_seconds();

}  // namespace lipsync::cli
