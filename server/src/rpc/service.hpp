// The LipSync service on gRPC's callback API. Each streaming call is a reactor
// object owned by gRPC until OnDone, defined next to its method in its own file
// (animate.cpp, subscribe.cpp; Render in render.cpp, ListModels and GetModel in
// models.cpp). The service holds what calls share: the model catalog, the
// session registry, the configuration, admission control and the face.
#pragma once

#include "catalog.hpp"
#include "face/face_capacity.hpp"
#include "face/face_stream.hpp"
#include "face/face_workers.hpp"
#include "lipsync/server/config.hpp"
#include "lipsync/tsan_handoff.hpp"
#include "metrics.hpp"
#include "rpc/live_decoders.hpp"
#include "rpc/speech_thread.hpp"
#include "sessions/audio_budget.hpp"
#include "sessions/live_streams.hpp"
#include "sessions/session.hpp"
#include "sessions/session_routing.hpp"
#include "transport/admission.hpp"
#include "transport/tenants.hpp"

// The generated base declares sync-API overloads of each method that the
// callback overrides hide on purpose.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Woverloaded-virtual"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace lipsync::server {

// Subscribe is a raw method: its reactor writes the bytes a session serialised
// once for all its subscribers (outbox.hpp); the request is parsed in subscribe.cpp.
class UnaryCall;

class LipSyncService final : public v1::LipSync::WithRawCallbackMethod_Subscribe<v1::LipSync::CallbackService> {
 public:
  LipSyncService(const ServerConfig& config, const ModelCatalog& catalog);

  grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage>* Animate(grpc::CallbackServerContext* context) override;
  grpc::ServerUnaryReactor* Render(grpc::CallbackServerContext* context, const v1::RenderRequest* request,
                                   v1::RenderResponse* response) override;
  grpc::ServerWriteReactor<grpc::ByteBuffer>* Subscribe(grpc::CallbackServerContext* context,
                                                        const grpc::ByteBuffer* request) override;
  grpc::ServerWriteReactor<v1::SpeakResponse>* Speak(grpc::CallbackServerContext* context,
                                                     const v1::SpeakRequest* request) override;
  grpc::ServerBidiReactor<v1::ListenRequest, v1::TrackMessage>* Listen(grpc::CallbackServerContext* context) override;
  grpc::ServerUnaryReactor* ListModels(grpc::CallbackServerContext* context, const v1::ListModelsRequest* request,
                                       v1::ListModelsResponse* response) override;
  grpc::ServerUnaryReactor* GetModel(grpc::CallbackServerContext* context, const v1::GetModelRequest* request,
                                     v1::ModelInfo* response) override;

  SessionRegistry& sessions() { return sessions_; }
  const ServerConfig& config() const { return config_; }
  const ModelCatalog& catalog() const { return catalog_; }
  /// Which calls the server takes on (--max-streams, the drain).
  Admission& admission() { return admission_; }
  /// The x-lipsync-session check and the words of a misrouted Subscribe's NOT_FOUND.
  SessionRouting& routing() { return routing_; }
  /// Meshes and rigs shared by the streams that ask for the mesh output (built lazily).
  FaceLibrary& faces() { return faces_; }
  /// The metrics every call adds to (metrics.hpp), and their registry (GET /metrics).
  ServerMetrics& metrics() { return metrics_; }
  MetricsRegistry& metrics_registry() { return metrics_registry_; }
  /// The streams running now (aborted with ABORTED at the drain deadline).
  LiveStreams& live_streams() { return live_streams_; }
  /// The low-priority threads the face runs on.
  FaceWorkers& face_workers() { return face_workers_; }
  /// The threads Listen streams decode on (--listen-threads), at normal priority; each stream has
  /// a lane (strand) of its own there.
  FaceWorkers& recognition_workers() { return recognition_workers_; }
  /// Decoders for Listen's live streams, loaded ahead (rpc/live_decoders.hpp).
  LiveDecoderPool& live_decoders() { return live_decoders_; }
  /// The one thread Speak synthesises on (espeak-ng is not re-entrant).
  SpeechThread& speech_thread() { return speech_thread_; }
  /// API keys, tenants and their quotas (--api-keys; open without).
  Tenants& tenants() { return tenants_; }
  /// How much mesh work is admitted (--max-mesh-streams-per-face-thread).
  FaceCapacity& face_capacity() { return face_capacity_; }
  /// The sound sessions keep for /audio, all together (--max-session-audio-bytes).
  AudioBudget& audio_budget() { return *audio_budget_; }

  /// The last statement of every call's OnDone, and Server's first after gRPC's Shutdown, which
  /// returns only once every OnDone has: what the calls wrote is Server's to destroy
  /// (tsan_handoff.hpp). A key of its own, so that it orders no call before another.
  void call_ended() const { handoff_release(&calls_ended_); }
  void after_every_call() const { handoff_acquire(&calls_ended_); }

 private:
  void register_gauges();
  /// ListModels and GetModel: counted as calls in progress (never refused) until their end.
  UnaryCall* start_model_query(const char* method, grpc::CallbackServerContext& context);
  /// The caller's API key checked for `method`, its tenant set on `call`.
  grpc::Status authenticate_model_query(const char* method, grpc::CallbackServerContext& context, UnaryCall& call);

  char calls_ended_ = 0;  // only its address: the key of call_ended
  const ServerConfig& config_;
  const ModelCatalog& catalog_;
  MetricsRegistry metrics_registry_;
  ServerMetrics metrics_{metrics_registry_};
  SessionRegistry sessions_;
  Admission admission_;
  SessionRouting routing_;
  Tenants tenants_;
  FaceLibrary faces_;
  FaceCapacity face_capacity_;
  // Shared with the audio strings it counts, which may outlive the service in a session.
  std::shared_ptr<AudioBudget> audio_budget_;
  // After what its jobs use, so that it is joined before they go.
  SpeechThread speech_thread_;
  LiveStreams live_streams_;
  // Before the face's, for the same reason: its destructor runs the Listen jobs still queued.
  FaceWorkers recognition_workers_;
  // Spare decoders for Listen, loaded on a thread of its own.
  LiveDecoderPool live_decoders_;
  // Last, so that it is destroyed first: its destructor runs the jobs still
  // queued, which use the members above.
  FaceWorkers face_workers_;
};
#pragma GCC diagnostic pop

}  // namespace lipsync::server
