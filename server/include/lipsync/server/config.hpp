// lipsyncd's configuration: listening address, admission limits, fan-out
// buffers and shutdown behaviour.
//
// Values come from defaults, then an optional JSON file (`--config FILE` or
// LIPSYNCD_CONFIG; keys are the flag names without the dashes), then
// environment variables (LIPSYNCD_ and the flag in capitals, `-` as `_`:
// LIPSYNCD_LISTEN, LIPSYNCD_MAX_STREAMS, ...; LIPSYNCD_MODEL is a
// comma-separated list of NAME=FILE), then command-line flags, each overriding
// the one before. Every value is checked once, here; a bad one throws
// ConfigError naming the flag (or file key, or variable) and the value.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace lipsync::server {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An extra articulation model given as `--model NAME=FILE`.
struct ModelFile {
  std::string name;
  std::string path;
  bool operator==(const ModelFile&) const = default;
};

struct ServerConfig {
  std::string listen = "127.0.0.1:50051";  ///< host:port; port 0 picks a free one
  /// host:port of the browser viewer (HTTP and WebSocket, docs/viewer.md); "" = off.
  std::string http_listen;
  std::int64_t drain_deadline_ms = 5000;  ///< on SIGTERM: time running streams get to finish

  // Admission limits (RESOURCE_EXHAUSTED beyond them).
  std::size_t max_streams = 10'000;                              ///< concurrent Animate + Subscribe streams
  std::size_t max_sessions = 10'000;                             ///< named sessions held (live or retained)
  std::size_t max_subscribers_per_session = 100;                 ///< concurrent subscribers of one session
  std::size_t max_phonemes = 100'000;                            ///< phonemes per utterance
  std::int64_t max_utterance_ms = 3'600'000;                     ///< utterance length (end of the last phoneme)
  std::size_t max_message_bytes = std::size_t{4} * 1024 * 1024;  ///< largest request message
  /// gRPC's memory quota for the transport (read buffers of every connection, call arenas);
  /// 0 = unbounded; unset = sized from max_message_bytes and the calls in progress
  /// (server/src/transport/transport_quota.hpp: a message over the limit then costs about 20 MB at idle).
  std::optional<std::size_t> transport_memory_bytes;
  /// The sound all sessions keep for /audio together (Speak's voice, producers' attached WAVs).
  std::size_t max_session_audio_bytes = std::size_t{256} * 1024 * 1024;

  // Sessions and fan-out.
  std::size_t replay_frames = 1'800;            ///< frames a session keeps for late joiners (1 min at 30 fps)
  std::size_t subscriber_queue_frames = 2'000;  ///< frames a subscriber may have waiting
  /// A subscriber cut off for falling behind whose last write still has not left
  /// (it stopped reading, so its RESOURCE_EXHAUSTED cannot be sent) is cancelled
  /// after this long, freeing its stream.
  std::int64_t stalled_subscriber_ms = 5'000;
  std::int64_t session_retention_ms = 10'000;  ///< how long a finished session stays joinable

  // Live audio (Listen).
  std::int64_t max_listen_ms = 28'800'000;  ///< audio one Listen stream may carry (8 hours)
  std::size_t listen_threads = 0;           ///< threads that run the recognisers; 0: one per core

  // The physics face (mesh output).
  std::size_t face_threads = 0;  ///< threads that run face solvers; 0: one per core
  /// Their scheduling: "idle" (SCHED_IDLE: only CPU time no other thread wants, so channel
  /// streams never wait for a face), "low" (nice 10) or "normal".
  std::string face_priority = "idle";
  /// Mesh work admitted, in level-1 30 fps streams per face thread (a stream weighs its CPU
  /// need: server/src/face/face_capacity.hpp); beyond it mesh streams get RESOURCE_EXHAUSTED.
  std::size_t max_mesh_streams_per_face_thread = 16;
  /// An admitted mesh stream whose face falls further behind real time than this ends with
  /// DEADLINE_EXCEEDED.
  std::int64_t mesh_max_lag_ms = 3'000;

  std::string log_level = "info";   ///< trace, debug, info, warn, error, off
  std::string log_format = "text";  ///< text or json (one object per line)
  /// host:port of the Prometheus endpoint (GET /metrics); "" = none. Port 0 picks a free one.
  std::string metrics_listen;
  std::vector<ModelFile> models;  ///< extra models beside the built-in one
  /// How this replica names itself in errors about sessions it does not hold (a balancer
  /// misrouting shows in one look); "" = "<host name> (<listen address>)".
  std::string replica_name;

  // Transport security and callers (docs/security.md). Empty: off.
  std::string tls_cert;       ///< PEM certificate chain served to clients (with tls_key: TLS on)
  std::string tls_key;        ///< PEM private key of tls_cert
  std::string tls_client_ca;  ///< PEM CA bundle; when set, clients must present a certificate it signed (mTLS)
  std::string api_keys;       ///< JSON key file: hashed API keys, their tenants and quotas; "" = open server

  bool operator==(const ServerConfig&) const = default;
};

/// The result of reading the command line: a configuration, or a request for help.
struct CommandLine {
  ServerConfig config;
  bool help = false;
};

/// Reads one environment variable; nullopt when it is not set.
using Environment = std::function<std::optional<std::string>(const std::string& name)>;
/// The process environment (getenv).
Environment process_environment();
/// The variable that sets `flag`: "--max-streams" -> "LIPSYNCD_MAX_STREAMS".
std::string environment_variable(const std::string& flag);

/// Parses `args` (without the program name), with `environment` under the flags (none by
/// default). Throws ConfigError.
CommandLine parse_command_line(const std::vector<std::string>& args, const Environment& environment = {});

/// The `--help` text: every flag with its default.
std::string help_text();

}  // namespace lipsync::server
