// The browser viewer: an optional HTTP port (--http-listen) that serves a single-page face viewer
// (server/web/, embedded at build time) and a WebSocket that follows a session.
//
// Routes (docs/viewer.md):
//   GET  /  and  /view            the page (query: session, audio, start)
//   GET  /viewer.js, /viewer.css  its script and style (with face_drawing.js, audio_steering.js and the
//                                 others of server/web/); /face.json: the viewer's face (data/face/)
//   GET  /ws?session=NAME[&start=now][&wait_s=S]
//                                       WebSocket: every TrackMessage of the session, serialised,
//                                       one binary message each (header, batches, summary); then a
//                                       close with 1000 and "OK", or a text message
//                                       {"code":"NOT_FOUND","message":"..."} and close code
//                                       4000 + the gRPC status code with the message as reason.
//                                       With wait_s, a session not started yet is waited for up to
//                                       S seconds, first saying {"waiting":NAME,"wait_s":S}
//   GET  /listen?session=NAME&rate=HZ[&...]
//                                       WebSocket: a live voice from the page. Binary messages are
//                                       16-bit PCM pieces (at most 64 KiB, at most 2 s ahead of
//                                       real time), the text message {"end": true} ends it; one
//                                       Listen call hears them into the session, which the page
//                                       follows on /ws. Then {"session","frames","duration_us",
//                                       "notes"} and close 1000, or an error as /ws closes
//   POST /sessions?session=NAME&...     body: phoneme text in any format the CLI reads; the
//                                       server animates it as a session (a quick try); with
//                                       speak=1 the body is text that a Speak call speaks into it
//   GET  /audio?session=NAME            the session's sound as a WAV file (a Speak session's
//                                       voice, kept by the session); 404 when it has none
//
// Nothing here duplicates the service: a follower is a Subscribe call, a quick try an Animate
// call and a page's voice a Listen call, all made over the gRPC server's in-process channel, so admission, limits,
// routing, replay and the media-clock anchor are exactly those of a gRPC client. Each HTTP
// connection is served by its own thread with Beast's synchronous API: a viewer is for a few
// people watching, not for fan-out at scale (that is Subscribe's job).
#pragma once

#include <grpcpp/support/status.h>

#include <atomic>
#include <boost/asio/ip/tcp.hpp>
#include <functional>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace grpc {
class Channel;
class ClientContext;
}  // namespace grpc

namespace lipsync::server {

class ModelCatalog;

/// A session's WAV for GET /audio: authenticates `authorization` (the request's `Authorization`
/// value, null if none) as a Subscribe would, finds `session` in the caller's tenant and sets
/// `wav`; NOT_FOUND when there is no such session or it has no audio.
using SessionAudioLookup = std::function<grpc::Status(const std::string_view* authorization, const std::string& session,
                                                      std::shared_ptr<const std::string>& wav)>;

/// Whether `session` exists for the caller (`authorization` as for SessionAudioLookup): OK when
/// it does, NOT_FOUND saying where sessions live when not, or the caller's refusal. Asked while a
/// follower waits for its session to start; it makes no call and logs nothing.
using SessionProbe = std::function<grpc::Status(const std::string_view* authorization, const std::string& session)>;

class HttpViewer {
 public:
  /// Binds `host_port` (port 0 picks a free one) and starts accepting. `service` is a channel to
  /// the LipSync service (the gRPC server's in-process channel); `catalog` chooses the phone set of
  /// pasted text; `session_audio` serves /audio (without it, /audio answers 404); `session_probe`
  /// lets /ws wait for a session to start (without it, wait_s is not waited for).
  /// Throws std::runtime_error saying why it cannot listen.
  HttpViewer(const std::string& host_port, std::shared_ptr<grpc::Channel> service, const ModelCatalog& catalog,
             SessionAudioLookup session_audio = {}, SessionProbe session_probe = {});
  ~HttpViewer();
  HttpViewer(const HttpViewer&) = delete;
  HttpViewer& operator=(const HttpViewer&) = delete;

  /// "host:port" with the bound port.
  std::string address() const;
  int port() const;

  /// Stops accepting, cancels every follower and quick try (their WebSockets get 1001 "going
  /// away"), closes the connections and waits for their threads. Idempotent.
  void close();

 private:
  struct Connection;
  void accept_loop();
  void serve(Connection& connection);
  void reap_finished_locked();

  std::string host_;
  std::shared_ptr<grpc::Channel> service_;
  const ModelCatalog& catalog_;
  SessionAudioLookup session_audio_;
  SessionProbe session_probe_;
  boost::asio::io_context io_;
  boost::asio::ip::tcp::acceptor acceptor_;
  int port_ = 0;
  std::atomic<bool> closing_{false};
  std::mutex mutex_;
  std::list<std::unique_ptr<Connection>> connections_;
  std::thread accept_thread_;
};

}  // namespace lipsync::server
