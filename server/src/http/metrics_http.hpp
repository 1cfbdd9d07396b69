// The Prometheus endpoint (--metrics-listen HOST:PORT, off by default): HTTP/1.1
// with Boost.Beast on one thread of its own, away from gRPC's. GET /metrics
// answers 200 with the registry's exposition (text/plain; version=0.0.4);
// another path is 404, another method 405. One request per connection
// (Connection: close); a client gets 5 s to send its request and read the answer,
// so a stalled scraper cannot hold the thread.
#pragma once

#include <functional>
#include <memory>
#include <string>

namespace lipsync::server {

class MetricsEndpoint {
 public:
  /// Binds `host_port` (port 0 picks one) and serves `exposition()` from a thread.
  /// Throws std::runtime_error if it cannot listen.
  MetricsEndpoint(const std::string& host_port, std::function<std::string()> exposition);
  ~MetricsEndpoint();
  MetricsEndpoint(const MetricsEndpoint&) = delete;
  MetricsEndpoint& operator=(const MetricsEndpoint&) = delete;

  /// "host:port" with the bound port.
  std::string address() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lipsync::server
