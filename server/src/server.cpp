// Server: builds the gRPC server around LipSyncService (health checking and
// reflection on), and shuts it down with a drain deadline.
//
// The drain is for rolling restarts behind a load balancer: the listener closes
// and every connection gets a GOAWAY at once (gRPC's Shutdown), so new sessions
// are opened on another replica (nginx and Envoy retry a refused connection
// elsewhere, which they never do for a call that got a status), while the
// streams already running here finish.
#include "lipsync/server/server.hpp"

#include <atomic>
#include <mutex>
#include <stdexcept>
#include <thread>

#include <grpc/grpc.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/spdlog.h>

#include "catalog.hpp"
#include "service.hpp"

namespace lipsync::server {

struct Server::Impl {
  explicit Impl(ServerConfig config_in)
      : config(std::move(config_in)), catalog(config.models), service(config, catalog) {}

  ServerConfig config;
  ModelCatalog catalog;
  LipSyncService service;
  std::unique_ptr<grpc::Server> server;
  int port = 0;
  std::once_flag shutdown_once;
};

Server::Server(ServerConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {
  spdlog::set_level(spdlog::level::from_str(impl_->config.log_level));
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder builder;
  builder.AddListeningPort(impl_->config.listen, grpc::InsecureServerCredentials(), &impl_->port);
  builder.SetMaxReceiveMessageSize(static_cast<int>(impl_->config.max_message_bytes));
  builder.RegisterService(&impl_->service);
  impl_->server = builder.BuildAndStart();
  if (!impl_->server || impl_->port == 0) {
    throw std::runtime_error("cannot listen on " + impl_->config.listen);
  }
  impl_->service.routing().set_bound_address(address());
}

Server::~Server() { shutdown(std::chrono::milliseconds(0)); }

int Server::port() const { return impl_->port; }

std::string Server::address() const {
  const std::string& listen = impl_->config.listen;
  return listen.substr(0, listen.rfind(':')) + ":" + std::to_string(impl_->port);
}

void Server::shutdown(std::chrono::milliseconds drain) {
  std::call_once(impl_->shutdown_once, [&] {
    // gRPC's Shutdown(deadline) closes the listener and sends GOAWAY at once, lets
    // the running calls finish until the deadline, then cancels them. It also
    // waits, until the deadline, for connections that stay open with no call on
    // them (an idle client keeps its channel), so it runs on a thread of its own
    // while this one watches the calls: once none is running, the remaining
    // connections are closed (grpc_server_cancel_all_calls, repeated until
    // Shutdown returns, since it may have not begun when first asked). Calls that
    // slip in before the GOAWAY reaches their client get UNAVAILABLE.
    if (auto* health = impl_->server->GetHealthCheckService()) health->Shutdown();
    impl_->service.admission().begin_drain();
    std::atomic<bool> stopped = false;
    std::thread stopper([&] {
      impl_->server->Shutdown(std::chrono::system_clock::now() + drain);
      stopped = true;
    });
    const auto deadline = std::chrono::steady_clock::now() + drain;
    while (impl_->service.admission().calls_in_progress() > 0 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    while (!stopped) {
      grpc_server_cancel_all_calls(impl_->server->c_server());
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    stopper.join();
    impl_->server->Wait();
  });
}

std::size_t Server::active_streams() const { return impl_->service.admission().active_streams(); }

std::size_t Server::session_count() const { return impl_->service.sessions().size(); }

}  // namespace lipsync::server
