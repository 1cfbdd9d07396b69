// AnimationClient: the C++ client of lipsyncd's lipsync.v1.LipSync service.
//
//   render     one utterance in, the whole track out (unary, blocking)
//   animate    an Animate stream: settings, phoneme chunks as the caller
//              produces them, an end marker; every TrackMessage goes to a
//              handler as it arrives (callback API: no thread per stream)
//   subscribe  follow a session's frames until its producer finishes
//   speak      text in; the server speaks it (espeak-ng) and returns the audio
//              and the track of what it spoke, on one utterance clock (blocking)
//   listen     a Listen stream: settings, audio pieces as they are produced, an
//              end marker; the frames go to a handler as they arrive
//
// Every call that names a session (an Animate with settings.session, a Subscribe)
// also sends it as the metadata `x-lipsync-session`, on which a load balancer in
// front of several lipsyncd replicas routes (docs/deploy.md).
//
// The channel is plaintext unless ClientOptions::tls asks for TLS (a CA to trust,
// and a client certificate for a server that requires one); with an API key
// every call carries `authorization: Bearer <key>` (docs/security.md).
//
// Every call carries a deadline (ClientOptions). A failed call becomes a
// CallError with the gRPC status code and the server's message, prefixed with
// what was being done and where, e.g. "Animate on 127.0.0.1:50051 failed:
// INVALID_ARGUMENT: phoneme 3: ...".
//
// Message handlers run on gRPC's threads, one message at a time per call, and
// must return quickly (append to a buffer, record a time); they must not throw.
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/track.hpp"
#include "lipsync/utterance.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"
#include "lipsync/visemes.hpp"

namespace lipsync::client {

namespace v1 = ::lipsync::v1;

/// The metadata key that carries a call's session name, for load balancers (docs/deploy.md).
inline constexpr std::string_view kSessionMetadataKey = "x-lipsync-session";

/// "INVALID_ARGUMENT" for grpc::StatusCode::INVALID_ARGUMENT, and so on (lipsync::grpc_status_code_name).
std::string_view status_code_name(grpc::StatusCode code);

/// A call that ended with a status other than OK.
class CallError : public std::runtime_error {
 public:
  /// `what` reads "<context> failed: <CODE>: <message>".
  CallError(std::string_view context, grpc::StatusCode code, std::string message);
  grpc::StatusCode code() const noexcept { return code_; }
  const std::string& server_message() const noexcept { return message_; }

 private:
  grpc::StatusCode code_;
  std::string message_;
};

/// The metadata key that carries a call's API key ("Bearer <key>").
inline constexpr std::string_view kAuthorizationMetadataKey = "authorization";

/// Transport security of the channel. Default: plaintext.
struct TlsOptions {
  bool enabled = false;   ///< TLS on; also implied by any file below
  std::string ca_file;    ///< PEM CA bundle that signed the server's certificate; "": the system's roots
  std::string cert_file;  ///< PEM client certificate for a server that requires one (mTLS); needs key_file
  std::string key_file;   ///< PEM private key of cert_file

  bool on() const { return enabled || !ca_file.empty() || !cert_file.empty() || !key_file.empty(); }
};

struct ClientOptions {
  std::chrono::milliseconds connect_timeout{5000};        ///< wait_connected()
  std::chrono::milliseconds unary_timeout{30000};         ///< Render, ListModels, GetModel
  std::chrono::milliseconds stream_timeout{3600 * 1000};  ///< whole Animate / Subscribe stream
  TlsOptions tls;                                         ///< plaintext unless asked
  std::string api_key;  ///< sent as `authorization: Bearer <key>` on every call; "": none
};

/// The channel credentials for `tls`: insecure when it is off. Throws CallError
/// (INVALID_ARGUMENT) naming a file that cannot be read, or a certificate without its key.
std::shared_ptr<grpc::ChannelCredentials> channel_credentials(const TlsOptions& tls);
/// What to check when lipsyncd at an address does not answer, in parentheses: that it runs
/// there and, with `tls` off, that it does not need TLS; with it on, that the files match.
std::string unreachable_hint(const TlsOptions& tls);
/// Adds `authorization: Bearer <api_key>` to `context` (nothing for an empty key).
void add_api_key(grpc::ClientContext& context, const std::string& api_key);

/// A track as received: the header, the frames gathered into a core Track
/// (channel values; arkit weights beside it) and the summary.
struct ReceivedTrack {
  v1::TrackHeader header;
  Track track;               ///< channel_count = header.channels_size(), fps = header.fps()
  std::vector<float> arkit;  ///< frame_count() × header.arkit_names_size()
  /// With the mesh output (header.has_mesh()): frame_count() × header.mesh().vertex_count() × 3
  /// vertex coordinates in metres, int16 batches decoded as offset + scale × q; empty otherwise.
  std::vector<float> mesh_positions;
  /// With the viseme output (header.viseme_names() not empty): frame_count() × header.viseme_names_size()
  /// weights, frame-major; empty otherwise.
  std::vector<float> viseme_weights;
  /// With the viseme output: every event received, in time order (viseme = index into header.viseme_names()).
  std::vector<VisemeEvent> viseme_events;
  std::optional<v1::TrackSummary> summary;
  std::uint64_t first_frame = 0;  ///< track index of track.t_us[0] (> 0 for a subscriber joining late)

  /// Takes one stream message. Throws CallError (INTERNAL) naming the problem when
  /// the server breaks the protocol (frames before the header, wrong sizes,
  /// times not increasing, a gap in frame indices after the first batch, a viseme
  /// event that names no viseme or starts at none of its batch's frames).
  void add(const v1::TrackMessage& message);
  void add_frames(const v1::FrameBatch& batch);
};

/// What a Speak call returned: the speech and its frames on one utterance clock
/// (audio sample n plays at n × 10⁶ / header.sample_rate_hz() µs, frame t_us at t_us).
struct SpokenTrack {
  v1::SpeakHeader header;  ///< the audio's format, the phonemes animated; header.track(): the frames' TrackHeader
  std::vector<std::int16_t> samples;  ///< the whole audio, mono, at header.sample_rate_hz()
  ReceivedTrack track;                ///< the frames, as render() and animate() return them
  std::optional<v1::SpeakSummary> summary;

  /// Takes one Speak message. Throws CallError (INTERNAL) naming the problem when the
  /// server breaks the protocol (content before the header, an audio chunk that does
  /// not continue the audio, an odd byte count, more samples than announced).
  void add(const v1::SpeakResponse& message);
};

FrameKind to_core(v1::FrameKind kind);

/// One phoneme for the wire.
v1::Phoneme to_wire(const LabeledInterval& interval);

using MessageHandler = std::function<void(const v1::TrackMessage&)>;
/// Called once when a stream is over, on a gRPC thread, as the call's last act.
/// It must not destroy the call itself (post that to another thread).
using DoneHandler = std::function<void(const grpc::Status&)>;

namespace detail {
template <class Request>
class ProducerReactor;
class SubscribeReactor;
}  // namespace detail

/// A running Animate stream. Thread-safe: send() and end() may be called from
/// any thread while messages arrive on gRPC's threads.
class AnimateCall {
 public:
  ~AnimateCall();  ///< cancels the stream if it is still running, and waits for it
  AnimateCall(const AnimateCall&) = delete;
  AnimateCall& operator=(const AnimateCall&) = delete;

  /// Queues a chunk of phonemes. Returns false once the stream has ended (the
  /// server closed it: wait() says why).
  bool send(std::vector<v1::Phoneme> phonemes);
  /// Queues a piece of the utterance's WAV file for the session's viewers (AudioAttachment:
  /// the pieces in order, each within the server's message limit, before the first phonemes).
  /// Returns false once the stream has ended.
  bool send_audio(std::string wav_piece);
  /// Queues the end marker and closes the sending side.
  void end();
  /// Asks the server to drop the stream (it ends with CANCELLED).
  void cancel();
  /// Blocks until the stream is over; the final status.
  grpc::Status wait();
  bool done() const;

 private:
  friend class AnimationClient;
  explicit AnimateCall(std::unique_ptr<detail::ProducerReactor<v1::AnimateRequest>> reactor);
  std::unique_ptr<detail::ProducerReactor<v1::AnimateRequest>> reactor_;
};

/// A running Listen stream: audio in, frames back. Thread-safe as AnimateCall.
class ListenCall {
 public:
  ~ListenCall();  ///< cancels the stream if it is still running, and waits for it
  ListenCall(const ListenCall&) = delete;
  ListenCall& operator=(const ListenCall&) = delete;

  /// Queues the next bytes of the audio, in the settings' encoding (each piece within the
  /// server's message limit). Returns false once the stream has ended (wait() says why).
  bool send_audio(std::string bytes);
  /// Queues more words of the transcript (`text`, or `timed` words: ListenWords); the settings
  /// must have a transcript. Returns false once the stream has ended.
  bool send_words(v1::ListenWords words);
  /// Queues the end marker (the audio has ended) and closes the sending side.
  void end();
  /// Asks the server to drop the stream (it ends with CANCELLED).
  void cancel();
  /// Blocks until the stream is over; the final status.
  grpc::Status wait();
  bool done() const;

 private:
  friend class AnimationClient;
  explicit ListenCall(std::unique_ptr<detail::ProducerReactor<v1::ListenRequest>> reactor);
  std::unique_ptr<detail::ProducerReactor<v1::ListenRequest>> reactor_;
};

/// A running Subscribe stream.
class SubscribeCall {
 public:
  ~SubscribeCall();
  SubscribeCall(const SubscribeCall&) = delete;
  SubscribeCall& operator=(const SubscribeCall&) = delete;

  void cancel();
  grpc::Status wait();
  /// Waits at most `timeout`; nullopt if the stream is still running.
  std::optional<grpc::Status> wait_for(std::chrono::milliseconds timeout);
  bool done() const;

 private:
  friend class AnimationClient;
  explicit SubscribeCall(std::unique_ptr<detail::SubscribeReactor> reactor);
  std::unique_ptr<detail::SubscribeReactor> reactor_;
};

class AnimationClient {
 public:
  /// A client for lipsyncd at `address` ("127.0.0.1:50051", "localhost:50051",
  /// "unix:/path"), with TLS if options.tls asks for it. Connects lazily; see
  /// wait_connected(). Throws CallError if a TLS file cannot be read.
  explicit AnimationClient(std::string address, ClientOptions options = {});

  const std::string& address() const { return address_; }
  const ClientOptions& options() const { return options_; }

  /// Waits until the channel is connected. Throws CallError (UNAVAILABLE)
  /// saying the server cannot be reached at address() within connect_timeout.
  void wait_connected() const;

  /// Renders a whole utterance. Throws CallError.
  ReceivedTrack render(const v1::AnimationSettings& settings, std::span<const v1::Phoneme> phonemes) const;

  /// Starts an Animate stream and sends `settings`; messages go to `handler`.
  std::unique_ptr<AnimateCall> start_animate(const v1::AnimationSettings& settings, MessageHandler handler,
                                             DoneHandler on_done = {}) const;
  /// Sends `chunks` as fast as possible, then the end marker; returns what came
  /// back (every message also goes to `handler` if given). Throws CallError.
  ReceivedTrack animate(const v1::AnimationSettings& settings, std::span<const std::vector<v1::Phoneme>> chunks,
                        const MessageHandler& handler = {}) const;

  /// Starts a Listen stream and sends `settings`; the frames go to `handler` as they come.
  std::unique_ptr<ListenCall> start_listen(const v1::ListenSettings& settings, MessageHandler handler,
                                           DoneHandler on_done = {}) const;
  /// Starts following `session`; messages go to `handler`.
  std::unique_ptr<SubscribeCall> start_subscribe(const std::string& session, v1::SubscribeRequest::Start start,
                                                 MessageHandler handler, DoneHandler on_done = {}) const;
  /// Follows `session` until its producer finishes. Throws CallError.
  ReceivedTrack subscribe(const std::string& session, v1::SubscribeRequest::Start start,
                          const MessageHandler& handler = {}) const;

  /// Speaks `request.text()` on the server and returns the audio and its track;
  /// every message also goes to `handler` if given. With request.settings().session()
  /// the frames are published for subscribers too. Throws CallError.
  SpokenTrack speak(const v1::SpeakRequest& request,
                    const std::function<void(const v1::SpeakResponse&)>& handler = {}) const;

  v1::ListModelsResponse list_models() const;
  v1::ModelInfo get_model(const std::string& name) const;

 private:
  std::string address_;
  ClientOptions options_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::LipSync::Stub> stub_;
};

}  // namespace lipsync::client
