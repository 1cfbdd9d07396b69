// The LipSync service: requests become engine calls, frames become messages.
//
// Every call resolves its AnimationSettings once into a Plan (plan.hpp) and
// rejects bad values with INVALID_ARGUMENT naming the field. Phonemes go one at
// a time through a PhonemeInput (phoneme_input.hpp), so a bad phoneme is
// reported with its index whatever the chunking. Animate (animate.cpp) feeds
// the segments to a StreamingRenderer and sends, after each chunk, every frame
// the renderer released as FrameBatch messages (wire.hpp); Render (render.cpp)
// uses render_track. With lookahead 7 the two are equal bit for bit. Subscribe
// (subscribe.cpp) follows a named session's messages. Admission control
// (admission.hpp) counts streams and calls.
//
// This file builds what the calls share.
#include "service.hpp"

#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <thread>

namespace lipsync::server {
namespace {

std::size_t face_thread_count(const ServerConfig& config) {
  return config.face_threads > 0 ? config.face_threads : std::max(1u, std::thread::hardware_concurrency());
}

FaceWorkers::Priority face_priority(const std::string& name) {
  if (name == "idle") return FaceWorkers::Priority::idle;
  if (name == "low") return FaceWorkers::Priority::low;
  return FaceWorkers::Priority::normal;
}

}  // namespace

LipSyncService::LipSyncService(const ServerConfig& config, const ModelCatalog& catalog)
    : config_(config),
      catalog_(catalog),
      sessions_(config.max_sessions, config.replay_frames, std::chrono::milliseconds(config.session_retention_ms)),
      admission_(config.max_streams),
      routing_(config.replica_name, config.listen),
      tenants_(config.api_keys),
      face_capacity_(config.max_mesh_streams_per_face_thread, face_thread_count(config)),
      audio_budget_(std::make_shared<AudioBudget>(config.max_session_audio_bytes)),
      recognition_workers_(
          config.listen_threads > 0 ? config.listen_threads : std::max(1u, std::thread::hardware_concurrency()),
          FaceWorkers::Priority::normal),
      face_workers_(face_thread_count(config), face_priority(config.face_priority)) {
  register_gauges();
}

void LipSyncService::register_gauges() {
  metrics_registry_.gauge(
      {"lipsyncd_build_info", "lipsyncd's version and gRPC's; always 1.", {"version", "grpc_version"}, [] {
         return std::vector<GaugeSample>{{{LIPSYNCD_VERSION, grpc::Version()}, 1}};
       }});
  // A tenant's series appear with its first stream and stay (at 0 when idle); an open
  // server's one tenant "" has them from the start.
  if (tenants_.open()) {
    for (const char* method : {"Animate", "Subscribe"}) metrics_.open_streams.with({method, ""});
  }
  metrics_registry_.gauge(
      {"lipsyncd_streams", "Animate and Subscribe streams by state and tenant.", {"method", "state", "tenant"}, [this] {
         std::vector<GaugeSample> samples;
         metrics_.open_streams.each([&](const LabelValues& method_tenant, const Level& open) {
           samples.push_back({{method_tenant[0], "open", method_tenant[1]}, static_cast<double>(open.value())});
         });
         return samples;
       }});
  metrics_registry_.gauge({"lipsyncd_sessions",
                           "Named sessions held, by state (live, or ended and retained) and tenant.",
                           {"state", "tenant"},
                           [this] {
                             auto by_tenant = sessions_.counts_by(
                                 [this](const std::string& key) { return tenants_.tenant_of_session_key(key); });
                             metrics_.open_streams.each([&](const LabelValues& method_tenant, const Level&) {
                               by_tenant.try_emplace(method_tenant[1]);
                             });
                             std::vector<GaugeSample> samples;
                             for (const auto& [tenant, counts] : by_tenant) {
                               samples.push_back({{"live", tenant}, static_cast<double>(counts.live)});
                               samples.push_back({{"ended", tenant}, static_cast<double>(counts.ended)});
                             }
                             return samples;
                           }});
  metrics_registry_.gauge({"lipsyncd_session_subscribers", "Subscribers attached to sessions.", {}, [this] {
                             return std::vector<GaugeSample>{{{}, static_cast<double>(sessions_.counts().subscribers)}};
                           }});
  metrics_registry_.gauge({"lipsyncd_calls_in_progress", "Animate, Subscribe and Render calls running.", {}, [this] {
                             return std::vector<GaugeSample>{{{}, static_cast<double>(admission_.calls_in_progress())}};
                           }});
  metrics_registry_.gauge({"lipsyncd_listen_spare_decoders",
                           "Decoders loaded ahead for Listen's next live streams, ready to be taken.",
                           {},
                           [this] {
                             return std::vector<GaugeSample>{{{}, static_cast<double>(live_decoders_.ready())}};
                           }});
  metrics_registry_.gauge(
      {"lipsyncd_queued_messages",
       "Messages queued for streams, not yet handed to gRPC (all streams together).",
       {},
       [this] {
         return std::vector<GaugeSample>{{{}, static_cast<double>(metrics_.queued_messages.load())}};
       }});
}

}  // namespace lipsync::server
