// The two clients `lipsync loadtest` can carry its calls with, behind one
// small interface, so that the load test itself (timing, checking, report)
// does not know which one runs:
//
// - h2 (the default): the generator's own gRPC client on nghttp2
//   (h2_grpc_connection.hpp), every stream on the load test's Asio thread,
//   requests serialised once per utterance. Plaintext only.
// - grpc: the project's client library (lipsync::client::AnimationClient,
//   gRPC's C++ callback API), as an application would use it; also with TLS.
//
// Handlers: with h2 they run on the load test's thread; with grpc on gRPC's
// threads, so the load test hands its own work over with asio::post either way.
// A done handler must not destroy its call (post that).
#pragma once

#include <boost/asio/io_context.hpp>
#include <cstddef>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/client/animation_client.hpp"

namespace lipsync::cli {

/// An utterance's requests in the forms the clients send: the phonemes as
/// messages (grpc) and, ready for the wire, gRPC-framed AnimateRequests (h2):
/// one per phoneme, then the end marker.
struct UtteranceRequests {
  std::vector<client::v1::Phoneme> phonemes;
  std::vector<std::string> framed;

  UtteranceRequests() = default;
  explicit UtteranceRequests(std::vector<client::v1::Phoneme> phonemes);
};

/// One Animate or Subscribe call of the load test.
class LoadCall {
 public:
  virtual ~LoadCall() = default;
  /// Sends phoneme `index` of the call's utterance; false once the call has ended (Subscribe: always).
  virtual bool send_phoneme(std::size_t index) = 0;
  /// Sends the end marker and closes the request side.
  virtual void end() = 0;
  /// Asks the server to drop the call; it ends with CANCELLED.
  virtual void cancel() = 0;
};

enum class LoadClientKind { h2, grpc };

/// Starts the load test's calls on its connections.
class LoadClient {
 public:
  virtual ~LoadClient() = default;
  virtual std::size_t connections() const = 0;
  /// Starts an Animate call on `connection` and sends `settings` (and the session as metadata).
  virtual std::unique_ptr<LoadCall> animate(std::size_t connection, const client::v1::AnimationSettings& settings,
                                            const UtteranceRequests& requests, client::MessageHandler on_message,
                                            client::DoneHandler on_done) = 0;
  /// Starts following `session` from its beginning on `connection`.
  virtual std::unique_ptr<LoadCall> subscribe(std::size_t connection, const std::string& session,
                                              client::MessageHandler on_message, client::DoneHandler on_done) = 0;
  /// Closes the connections (call it when no call is open): then they leave `io` no work.
  virtual void close() = 0;
};

/// `connections` connections to `address` of the chosen kind, each waited for (up to
/// options.connect_timeout). h2 runs on `io` and ignores options.tls (the caller refuses TLS for it).
/// Throws client::CallError (UNAVAILABLE) naming the address when a connection fails.
std::unique_ptr<LoadClient> connect_load_client(LoadClientKind kind, boost::asio::io_context& io,
                                                const std::string& address, const client::ClientOptions& options,
                                                int connections);

std::string_view load_client_name(LoadClientKind kind);

}  // namespace lipsync::cli
