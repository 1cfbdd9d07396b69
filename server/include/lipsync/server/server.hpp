// lipsyncd as a library: the LipSync gRPC service (Animate, Render, Subscribe,
// ListModels, GetModel) on the callback API, with health checking and
// reflection, listening on the configured address. The binary (main.cpp) adds
// flags and signal handling; tests start it in-process on 127.0.0.1:0.
#pragma once

#include <chrono>
#include <cstddef>
#include <memory>
#include <string>

#include "lipsync/server/config.hpp"

namespace lipsync::server {

class Server {
 public:
  /// Loads the models (throws lipsync::InputError for a bad model file), binds
  /// and starts serving. Throws std::runtime_error if it cannot listen, or if a
  /// TLS file or the key file cannot be used (the message names the file).
  explicit Server(ServerConfig config);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// The port actually bound (useful with port 0).
  int port() const;
  /// "host:port" with the bound port.
  std::string address() const;
  /// The browser viewer's "host:port" with its bound port (--http-listen); "" when it is off.
  std::string http_address() const;
  /// "host:port" of the Prometheus endpoint (--metrics-listen), "" when there is none.
  std::string metrics_address() const;

  /// Refuses new calls (UNAVAILABLE), lets running calls finish for up to
  /// `drain`, then cancels the rest and waits until every call has ended.
  /// Returns as soon as no call is running. Idempotent.
  void shutdown(std::chrono::milliseconds drain);

  /// shutdown's drain for a process about to end: returns once every call has ended and
  /// the connections have closed or had their grace (GOAWAY, then 50 ms to flush and
  /// close), without waiting for gRPC to tear down what only frees memory (that goes on
  /// in a thread of its own). The caller must then end the process (`_Exit`), never
  /// destroy the server. Idempotent with shutdown: only the first of the two drains.
  void drain_for_exit(std::chrono::milliseconds drain);

  /// SIGHUP: reads the TLS files and the key file again. A good TLS set is served
  /// to new connections within about a second, a good key file applies to new
  /// calls; a bad one is logged and the old one stays. Open streams are untouched.
  void reload_credentials();

  /// Animate and Subscribe streams currently open.
  std::size_t active_streams() const;
  /// Sessions currently held (live, or ended within the retention time).
  std::size_t session_count() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lipsync::server
