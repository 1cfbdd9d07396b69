// The load generator's shared parts (loadtest_shared.hpp).
#include "loadtest_shared.hpp"

#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cli_error.hpp"
#include "network.hpp"

namespace lipsync::cli {

std::string loopback_server_address(const Arguments& arguments) {
  std::string address = server_address(arguments);
  if (!is_loopback_address(address)) {
    throw UsageError("--server: '" + address +
                     "' is not on this machine; loadtest only runs against loopback "
                     "addresses (127.0.0.1:PORT, localhost:PORT, [::1]:PORT, unix:PATH)");
  }
  return address;
}

Percentiles percentiles(std::vector<std::int32_t>& values_us) {
  Percentiles result;
  if (values_us.empty()) return result;
  std::sort(values_us.begin(), values_us.end());
  const auto at = [&](double q) {
    const auto index = static_cast<std::size_t>(std::lround(q * static_cast<double>(values_us.size() - 1)));
    return static_cast<double>(values_us[index]) / 1000.0;
  };
  result.p50_ms = at(0.50);
  result.p95_ms = at(0.95);
  result.p99_ms = at(0.99);
  result.max_ms = static_cast<double>(values_us.back()) / 1000.0;
  return result;
}

nlohmann::json to_json(const Percentiles& p) {
  return {{"p50", p.p50_ms}, {"p95", p.p95_ms}, {"p99", p.p99_ms}, {"max", p.max_ms}};
}

std::string to_text(const Percentiles& p) {
  char text[128];
  std::snprintf(text, sizeof text, "p50 %.2f ms  p95 %.2f ms  p99 %.2f ms  max %.2f ms", p.p50_ms, p.p95_ms, p.p99_ms,
                p.max_ms);
  return text;
}

double process_cpu_seconds() {
  rusage usage{};
  ::getrusage(RUSAGE_SELF, &usage);
  const auto seconds = [](const timeval& time) {
    return static_cast<double>(time.tv_sec) + static_cast<double>(time.tv_usec) * 1e-6;
  };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

}  // namespace lipsync::cli
