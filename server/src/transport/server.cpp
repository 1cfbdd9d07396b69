// Server: builds the gRPC server around LipSyncService (health checking and
// reflection on), and shuts it down with a drain deadline.
//
// The drain is for rolling restarts behind a load balancer: the listener (our
// own, listener.hpp) closes at once, so a balancer's new connection is refused
// and the new session opens on another replica (nginx and Envoy retry a refused
// connection elsewhere, which they never do for a call that got a status),
// while the streams already running here finish on their connections.
//
// With TLS (tls.hpp) gRPC listens itself: it cannot take an accepted socket
// into a TLS channel. The drain then cannot refuse new connections before the
// end: it refuses new calls (UNAVAILABLE "the server is shutting down"), health
// says NOT_SERVING, running calls get the deadline, and gRPC's Shutdown closes
// the listener. The plaintext path is unchanged.
#include "lipsync/server/server.hpp"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/spdlog.h>

#include <future>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "call_log.hpp"
#include "catalog.hpp"
#include "http/http_viewer.hpp"
#include "http/metrics_http.hpp"
#include "lipsync/tsan_handoff.hpp"
#include "rpc/service.hpp"
#include "transport/listener.hpp"
#include "transport/tls.hpp"
#include "transport/transport_quota.hpp"

namespace lipsync::server {
namespace {

/// How long connections may take to flush and close after GOAWAY at the end of a drain.
constexpr auto kConnectionGrace = std::chrono::milliseconds(50);
// Streams aborted at the drain deadline get this long to send their ABORTED.
constexpr auto kAbortedGrace = std::chrono::milliseconds(1000);

}  // namespace

struct Server::Impl {
  explicit Impl(ServerConfig config_in)
      : transport_quota(), config(std::move(config_in)), catalog(config.models), service(config, catalog) {}

  // First, so that it goes last: the service's admission calls into it until the calls are gone.
  std::unique_ptr<TransportQuota> transport_quota;  // none with --transport-memory-bytes 0
  ServerConfig config;
  ModelCatalog catalog;
  LipSyncService service;
  std::unique_ptr<Listener> listener;  // plaintext only: with TLS gRPC listens
  std::unique_ptr<TlsCredentials> tls;
  std::unique_ptr<grpc::Server> server;
  std::unique_ptr<HttpViewer> viewer;        // --http-listen: follows sessions through the in-process channel
  std::unique_ptr<MetricsEndpoint> metrics;  // --metrics-listen
  int port = 0;
  std::once_flag shutdown_once;

  /// Closes the door, lets the calls finish (aborting those past `drain`) and gives the
  /// face threads their priority back: everything before GOAWAY.
  void drain_calls(std::chrono::milliseconds drain);

  /// Waits until no call is in progress (nor the first call of a connection accepted just
  /// now: admission.hpp), for at most `limit`; true if none is.
  bool wait_for_calls(std::chrono::milliseconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (service.admission().calls_in_progress() > 0 || service.admission().awaiting_first_calls()) {
      if (std::chrono::steady_clock::now() >= deadline) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    return true;
  }
};

Server::Server(ServerConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {
  spdlog::set_level(spdlog::level::from_str(impl_->config.log_level));
  set_log_format(impl_->config.log_format == "json" ? LogFormat::json : LogFormat::text);
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  const ServerConfig& settings = impl_->config;
  if (settings.tls_cert.empty() && settings.tls_key.empty() && settings.tls_client_ca.empty()) {
    impl_->listener = std::make_unique<Listener>(impl_->config.listen);  // throws: cannot listen
    impl_->port = impl_->listener->port();
  } else {
    impl_->tls = std::make_unique<TlsCredentials>(impl_->config);  // throws TlsError naming the file
    builder.AddListeningPort(impl_->config.listen, impl_->tls->server_credentials(), &impl_->port);
  }
  builder.SetMaxReceiveMessageSize(static_cast<int>(impl_->config.max_message_bytes));
  // The transport quota also bounds what a message over the limit costs (transport_quota.hpp).
  if (!impl_->config.transport_memory_bytes) {
    impl_->transport_quota =
        std::make_unique<TransportQuota>(TransportQuota::base_for(impl_->config.max_message_bytes), true);
    impl_->service.admission().follow_calls(
        [quota = impl_->transport_quota.get()](std::size_t calls) { quota->follow(calls); });
  } else if (*impl_->config.transport_memory_bytes > 0) {
    impl_->transport_quota = std::make_unique<TransportQuota>(*impl_->config.transport_memory_bytes, false);
  }
  if (impl_->transport_quota) builder.SetResourceQuota(impl_->transport_quota->resource_quota());
  builder.RegisterService(&impl_->service);
  handoff_release(&impl_->service);  // gRPC calls its handlers on its own threads from now on
  impl_->server = builder.BuildAndStart();
  if (!impl_->server || impl_->port == 0) {
    throw std::runtime_error("cannot start the gRPC server on " + impl_->config.listen);
  }
  impl_->service.routing().set_bound_address(address());
  handoff_release(&impl_->service);
  if (impl_->listener) impl_->listener->start(*impl_->server, impl_->service.admission().connections());
  spdlog::info("transport: {}", impl_->tls ? (impl_->config.tls_client_ca.empty()
                                                  ? "TLS (" + impl_->config.tls_cert + ")"
                                                  : "mutual TLS (" + impl_->config.tls_cert + ", clients of " +
                                                        impl_->config.tls_client_ca + ")")
                                           : std::string("plaintext (no --tls-cert)"));
  spdlog::info("callers: {}", impl_->service.tenants().describe());
  if (!impl_->config.http_listen.empty()) {
    // /audio: a session's sound, for whoever may Subscribe to it (the same key, tenant and retention).
    auto session_audio = [&service = impl_->service](const std::string_view* authorization, const std::string& session,
                                                     std::shared_ptr<const std::string>& wav) {
      Caller caller;
      if (auto status = service.tenants().authenticate_value(authorization, "Subscribe", caller); !status.ok()) {
        return status;
      }
      const std::shared_ptr<Session> found = service.sessions().find(caller.session_key(session));
      if (!found) return service.routing().not_held(session, service.config().session_retention_ms);
      wav = found->audio_wav();
      if (!wav) {
        return grpc::Status(grpc::StatusCode::NOT_FOUND,
                            "session '" + session +
                                "' has no audio: a session keeps its sound when made by Speak or when its producer "
                                "attached it (AnimateRequest.audio, `lipsync stream --audio FILE.wav`); give the "
                                "page ?audio=URL for the others");
      }
      return grpc::Status::OK;
    };
    // /ws?wait_s=: whether a session has started yet, for whoever may Subscribe to it.
    auto session_probe = [&service = impl_->service](const std::string_view* authorization,
                                                     const std::string& session) {
      Caller caller;
      if (auto status = service.tenants().authenticate_value(authorization, "Subscribe", caller); !status.ok()) {
        return status;
      }
      if (!service.sessions().find(caller.session_key(session))) {
        return service.routing().not_held(session, service.config().session_retention_ms);
      }
      return grpc::Status::OK;
    };
    impl_->viewer = std::make_unique<HttpViewer>(impl_->config.http_listen,
                                                 impl_->server->InProcessChannel(grpc::ChannelArguments()),
                                                 impl_->catalog, std::move(session_audio), std::move(session_probe));
  }
  if (!impl_->config.metrics_listen.empty()) {
    impl_->metrics = std::make_unique<MetricsEndpoint>(
        impl_->config.metrics_listen,
        [&registry = impl_->service.metrics_registry()] { return registry.exposition(); });
  }
}

std::string Server::metrics_address() const { return impl_->metrics ? impl_->metrics->address() : std::string(); }

Server::~Server() { shutdown(std::chrono::milliseconds(0)); }

int Server::port() const { return impl_->port; }

std::string Server::address() const {
  const std::string& listen = impl_->config.listen;
  return listen.substr(0, listen.rfind(':')) + ":" + std::to_string(impl_->port);
}

std::string Server::http_address() const { return impl_->viewer ? impl_->viewer->address() : std::string(); }

void Server::Impl::drain_calls(std::chrono::milliseconds drain) {
  // The viewer's followers are Subscribe calls of its own: end them (WebSocket 1001) first.
  if (viewer) viewer->close();
  // No new connections from now on; calls that still arrive on open connections
  // are refused with UNAVAILABLE; running calls get `drain` to finish. Only then
  // is gRPC shut down (GOAWAY, the rest cancelled): sent earlier, GOAWAY makes
  // gRPC 1.51 close each connection right after its last stream, racing that
  // stream's final frames (a balancer then reports the finished stream as reset).
  if (listener) {
    listener->close();
    spdlog::info("listener closed: new connections are refused");
  }
  if (auto* health = server->GetHealthCheckService()) health->Shutdown();
  service.admission().begin_drain();
  if (!wait_for_calls(drain)) {
    // Past the deadline: the streams still running end with ABORTED, as documented, and
    // get a moment to send it (a client that stopped reading never takes it: gRPC's
    // Shutdown below cancels those).
    const std::size_t aborted = service.live_streams().abort_all(
        {grpc::StatusCode::ABORTED, "the server is shutting down: the drain deadline (--drain-deadline-ms=" +
                                        std::to_string(drain.count()) + ") has passed"});
    spdlog::info("drain deadline passed: {} streams aborted", aborted);
    wait_for_calls(kAbortedGrace);
  }
  spdlog::debug("drain: no call left");
  // The face threads must not need CPU time nobody else wants to end (face_workers.hpp).
  if (!service.face_workers().restore_normal_priority()) {
    spdlog::info(
        "the face threads keep their low priority (no CAP_SYS_NICE, RLIMIT_NICE below 20): on a busy "
        "machine the process may take a while to end");
  }
}

// GOAWAY only once no call is left. A shutdown deadline already past would cut every
// connection at once, racing the final frames a connection may still be flushing (behind
// nginx: the last subscriber of a drained session got RST_STREAM INTERNAL_ERROR now and
// then). With the grace, a connection closes once its peer has it all (nginx closes an
// upstream connection after its response); only idle client connections still open are
// cut at its end.
void Server::shutdown(std::chrono::milliseconds drain) {
  std::call_once(impl_->shutdown_once, [&] {
    impl_->drain_calls(drain);
    impl_->server->Shutdown(std::chrono::system_clock::now() + kConnectionGrace);
    impl_->server->Wait();
    // Shutdown returned once every call's OnDone had, those of calls refused in the drain
    // (never counted as in progress) included.
    impl_->service.after_every_call();
  });
}

// The same drain, but the process ends at the grace's end, or before it once gRPC's
// Shutdown has returned (every connection closed). After the grace, gRPC would cut the
// idle connections and tear down its threads: hops from thread to thread that, on a
// machine with more runnable threads than cores, each wait for a time slice (tens of
// ms under load), only to free memory the process exit frees at once. The kernel cuts
// the connections as gRPC would have.
void Server::drain_for_exit(std::chrono::milliseconds drain) {
  std::call_once(impl_->shutdown_once, [&] {
    impl_->drain_calls(drain);
    const auto grace_end = std::chrono::steady_clock::now() + kConnectionGrace;
    auto shut_down = std::make_shared<std::promise<void>>();
    std::future<void> returned = shut_down->get_future();
    std::thread([server = impl_->server.get(), shut_down] {
      server->Shutdown(std::chrono::system_clock::now() + kConnectionGrace);
      shut_down->set_value();
    }).detach();
    const bool closed = returned.wait_until(grace_end) == std::future_status::ready;
    spdlog::debug(closed ? "drain: every connection closed" : "drain: the connection grace has passed");
  });
}

void Server::reload_credentials() {
  if (impl_->tls) {
    try {
      impl_->tls->reload();
      spdlog::info("SIGHUP: TLS files re-read: new connections get them within {} s", TlsCredentials::kRefreshSeconds);
    } catch (const TlsError& error) {
      spdlog::error("SIGHUP: TLS files not reloaded, the old ones stay: {}", error.what());
    }
  }
  if (!impl_->service.tenants().open()) {
    try {
      impl_->service.tenants().reload();
      spdlog::info("SIGHUP: API keys re-read: {}", impl_->service.tenants().describe());
    } catch (const KeyFileError& error) {
      spdlog::error("SIGHUP: API keys not reloaded, the old ones stay: {}", error.what());
    }
  }
}

std::size_t Server::active_streams() const { return impl_->service.admission().active_streams(); }

std::size_t Server::session_count() const { return impl_->service.sessions().size(); }

}  // namespace lipsync::server
