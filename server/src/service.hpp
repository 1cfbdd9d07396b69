// The LipSync service on gRPC's callback API. Each streaming call is a reactor
// object owned by gRPC until OnDone; the service holds what calls share: the
// model catalog, the session registry, the limits and the open-stream count.
#pragma once

#include <atomic>
#include <cstddef>

#include "catalog.hpp"
#include "face_stream.hpp"
#include "face_workers.hpp"
#include "lipsync/server/config.hpp"
#include "session.hpp"

// The generated base declares sync-API overloads of each method that the
// callback overrides hide on purpose.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Woverloaded-virtual"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace lipsync::server {

class LipSyncService final : public v1::LipSync::CallbackService {
 public:
  LipSyncService(const ServerConfig& config, const ModelCatalog& catalog);

  grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage>* Animate(
      grpc::CallbackServerContext* context) override;
  grpc::ServerUnaryReactor* Render(grpc::CallbackServerContext* context, const v1::RenderRequest* request,
                                   v1::RenderResponse* response) override;
  grpc::ServerWriteReactor<v1::TrackMessage>* Subscribe(grpc::CallbackServerContext* context,
                                                        const v1::SubscribeRequest* request) override;
  grpc::ServerUnaryReactor* ListModels(grpc::CallbackServerContext* context,
                                       const v1::ListModelsRequest* request,
                                       v1::ListModelsResponse* response) override;
  grpc::ServerUnaryReactor* GetModel(grpc::CallbackServerContext* context, const v1::GetModelRequest* request,
                                     v1::ModelInfo* response) override;

  std::size_t active_streams() const { return active_streams_.load(); }
  SessionRegistry& sessions() { return sessions_; }
  const ServerConfig& config() const { return config_; }
  const ModelCatalog& catalog() const { return catalog_; }
  /// Meshes and rigs shared by the streams that ask for the mesh output (built lazily).
  FaceLibrary& faces() { return faces_; }
  /// The low-priority threads the face runs on.
  FaceWorkers& face_workers() { return face_workers_; }

  /// Counts a new stream in, or says which limit it is over (or that the server is draining).
  grpc::Status admit_stream();
  void release_stream() {
    --active_streams_;
    --calls_in_progress_;
  }
  /// Render calls: counted for the drain only (they are not streams).
  grpc::Status admit_render();
  void release_render() { --calls_in_progress_; }
  /// From now on new calls are refused with UNAVAILABLE.
  void begin_drain() { draining_ = true; }
  /// Animate, Subscribe and Render calls running.
  std::size_t calls_in_progress() const { return calls_in_progress_.load(); }

 private:
  const ServerConfig& config_;
  const ModelCatalog& catalog_;
  SessionRegistry sessions_;
  FaceLibrary faces_;
  std::atomic<std::size_t> active_streams_{0};
  std::atomic<std::size_t> calls_in_progress_{0};
  std::atomic<bool> draining_{false};
  // Last, so that it is destroyed first: its destructor runs the jobs still
  // queued, which use the members above.
  FaceWorkers face_workers_;
};
#pragma GCC diagnostic pop

}  // namespace lipsync::server
