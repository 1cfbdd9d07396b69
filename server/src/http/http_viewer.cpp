#include "http_viewer.hpp"

#include <grpcpp/grpcpp.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>

#include <boost/asio/ip/address.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <charconv>
#include <chrono>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <thread>

#include "call_log.hpp"
#include "http/quick_try.hpp"
#include "http/web_assets.hpp"
#include "lipsync/error.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace lipsync::server {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = boost::asio::ip::tcp;
using Request = http::request<http::string_body>;
using Response = http::response<http::string_body>;

constexpr std::size_t kMaxBodyBytes = 4 * 1024 * 1024;  // pasted phoneme text
/// A WebSocket close reason is at most 123 bytes (RFC 6455, 5.5: 125 with the 2-byte code).
constexpr std::size_t kMaxCloseReasonBytes = 123;
/// Close codes 4000-4999 are for applications: ours is 4000 + the gRPC status code.
constexpr std::uint16_t kGrpcCloseCodeBase = 4000;
/// /ws?wait_s=S: the longest wait for a session that has not started, seconds.
constexpr int kMaxSessionWaitS = 3600;
/// While a follower waits, the session is looked for (and its WebSocket watched) this often.
constexpr int kSessionPollIntervalMs = 100;
/// /listen: the largest piece of a page's voice (about 0.34 s of 48 kHz stereo; a page sends 20 ms).
constexpr std::size_t kMaxPagePieceBytes = 64 * 1024;
/// /listen: how far a page's audio may run ahead of the time since its first piece (bursts after a
/// busy moment of the page), µs.
constexpr std::int64_t kMaxPageAudioLeadUs = 2'000'000;

Response text_response(const Request& request, http::status status, std::string body,
                       std::string_view content_type = "text/plain; charset=utf-8") {
  Response response(status, request.version());
  response.set(http::field::server, "lipsyncd");
  response.set(http::field::content_type, beast::string_view(content_type.data(), content_type.size()));
  response.set(http::field::cache_control, "no-store");
  response.keep_alive(request.keep_alive());
  response.body() = std::move(body);
  response.prepare_payload();
  return response;
}

/// The HTTP status that tells a browser what a gRPC status means.
http::status http_status(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK:
      return http::status::ok;
    case grpc::StatusCode::INVALID_ARGUMENT:
      return http::status::bad_request;
    case grpc::StatusCode::NOT_FOUND:
      return http::status::not_found;
    case grpc::StatusCode::ALREADY_EXISTS:
      return http::status::conflict;
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return http::status::too_many_requests;
    case grpc::StatusCode::UNAUTHENTICATED:
      return http::status::unauthorized;
    case grpc::StatusCode::PERMISSION_DENIED:
      return http::status::forbidden;
    case grpc::StatusCode::UNAVAILABLE:
      return http::status::service_unavailable;
    default:
      return http::status::internal_server_error;
  }
}

std::string error_json(const std::string& code, const std::string& message) {
  return nlohmann::json{{"code", code}, {"message", message}}.dump();
}

std::string truncated_reason(const std::string& message) {
  if (message.size() <= kMaxCloseReasonBytes) return message;
  std::size_t cut = kMaxCloseReasonBytes - 3;
  while (cut > 0 && (static_cast<unsigned char>(message[cut]) & 0xC0) == 0x80) --cut;  // not inside a UTF-8 character
  return message.substr(0, cut) + "...";
}

std::int64_t unix_now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

tcp::endpoint resolve(boost::asio::io_context& io, const std::string& host_port, std::string& host) {
  const auto colon = host_port.rfind(':');
  if (colon == std::string::npos)
    throw std::runtime_error("--http-listen: expected HOST:PORT, got '" + host_port + "'");
  host = host_port.substr(0, colon);
  std::string name = host;
  if (name.size() > 1 && name.front() == '[' && name.back() == ']') name = name.substr(1, name.size() - 2);
  tcp::resolver resolver(io);
  beast::error_code error;
  const auto results = resolver.resolve(name, host_port.substr(colon + 1), tcp::resolver::passive, error);
  if (error || results.empty()) {
    throw std::runtime_error("--http-listen: cannot resolve '" + host_port + "': " + error.message());
  }
  return results.begin()->endpoint();
}

}  // namespace

struct HttpViewer::Connection {
  explicit Connection(tcp::socket socket_in) : socket(std::move(socket_in)) {}

  tcp::socket socket;
  std::thread thread;
  std::atomic<bool> done{false};
  std::mutex call_mutex;
  grpc::ClientContext* call = nullptr;  ///< the follower's or quick try's call, cancelled by close()
};

namespace {

/// Registers `context` as the connection's running call (so close() can cancel it) for the
/// lifetime of this object; `admitted` is false when the viewer is already closing.
class CallRegistration {
 public:
  CallRegistration(std::mutex& mutex, grpc::ClientContext*& slot, grpc::ClientContext& context,
                   const std::atomic<bool>& closing)
      : mutex_(mutex), slot_(slot) {
    std::lock_guard lock(mutex_);
    admitted = !closing;
    if (admitted) slot_ = &context;
  }
  ~CallRegistration() {
    std::lock_guard lock(mutex_);
    slot_ = nullptr;
  }
  CallRegistration(const CallRegistration&) = delete;
  CallRegistration& operator=(const CallRegistration&) = delete;

  bool admitted = false;

 private:
  std::mutex& mutex_;
  grpc::ClientContext*& slot_;
};

/// The caller's API key on the in-process call (docs/viewer.md): the request's own
/// `Authorization` header, else `?key=` (a browser's WebSocket cannot set headers).
std::optional<std::string> authorization_value(const Request& request, const QueryParameters& query) {
  if (const auto header = request.find(http::field::authorization); header != request.end()) {
    return std::string(header->value());
  }
  if (const auto key = query.find("key"); key != query.end() && !key->second.empty()) return "Bearer " + key->second;
  return std::nullopt;
}

void forward_api_key(const Request& request, const QueryParameters& query, grpc::ClientContext& context) {
  if (const auto value = authorization_value(request, query)) context.AddMetadata("authorization", *value);
}

/// GET /audio?session=NAME: the session's WAV, from the bytes the session keeps (no copy).
bool serve_audio(tcp::socket& socket, const Request& request, const QueryParameters& query,
                 const SessionAudioLookup& lookup) {
  const auto fail = [&](http::status status, const std::string& code, const std::string& message) {
    beast::error_code error;
    http::write(socket, text_response(request, status, error_json(code, message), "application/json"), error);
    return !error && request.keep_alive();
  };
  if (request.method() != http::verb::get && request.method() != http::verb::head) {
    Response response = text_response(request, http::status::method_not_allowed, "/audio: only GET\n");
    response.set(http::field::allow, "GET, HEAD");
    beast::error_code error;
    http::write(socket, response, error);
    return !error && request.keep_alive();
  }
  const auto session = query.find("session");
  if (session == query.end() || session->second.empty()) {
    return fail(http::status::bad_request, "INVALID_ARGUMENT", "/audio needs a session: /audio?session=NAME");
  }
  std::shared_ptr<const std::string> wav;
  grpc::Status status(grpc::StatusCode::NOT_FOUND,
                      "session '" + session->second + "' has no audio (this lipsyncd keeps none)");
  if (lookup) {
    const std::optional<std::string> authorization = authorization_value(request, query);
    const std::string_view value = authorization ? std::string_view(*authorization) : std::string_view();
    status = lookup(authorization ? &value : nullptr, session->second, wav);
  }
  if (!status.ok())
    return fail(http_status(status.error_code()), code_name(status.error_code()), status.error_message());
  http::response<http::span_body<const char>> response(http::status::ok, request.version());
  response.set(http::field::server, "lipsyncd");
  response.set(http::field::content_type, "audio/wav");
  response.set(http::field::cache_control, "no-store");
  response.keep_alive(request.keep_alive());
  if (request.method() == http::verb::head) {
    response.content_length(wav->size());
  } else {
    response.body() = http::span_body<const char>::value_type(wav->data(), wav->size());
    response.prepare_payload();
  }
  beast::error_code error;
  http::write(socket, response, error);
  return !error && request.keep_alive();
}

/// Answers the upgrade `request` on `ws`; false when the handshake fails.
bool accept_upgrade(websocket::stream<tcp::socket&>& ws, const Request& request) {
  ws.set_option(websocket::stream_base::decorator(
      [](websocket::response_type& response) { response.set(http::field::server, "lipsyncd"); }));
  beast::error_code error;
  ws.accept(request, error);
  return !error;
}

/// Closes a WebSocket because lipsyncd shuts down (1001).
void close_going_away(websocket::stream<tcp::socket&>& ws) {
  beast::error_code ignored;
  ws.close(websocket::close_reason(websocket::close_code::going_away, "lipsyncd is shutting down"), ignored);
}

/// Ends a WebSocket with a gRPC error: the text message {"code", "message"}, then a close with
/// 4000 + the code and the message as its reason (cut to what a reason holds).
void close_with_status(websocket::stream<tcp::socket&>& ws, grpc::StatusCode code, const std::string& message) {
  beast::error_code ignored;
  ws.text(true);
  ws.write(boost::asio::buffer(error_json(code_name(code), message)), ignored);
  websocket::close_reason reason(truncated_reason(message));
  reason.code = static_cast<std::uint16_t>(kGrpcCloseCodeBase + code);
  ws.close(reason, ignored);
}

/// How a follower's WebSocket went, for its log line.
struct FollowOutcome {
  std::chrono::milliseconds waited{0};  ///< spent waiting for the session to start
  int gave_up_after_s = 0;              ///< > 0: the session did not start within this
};

/// Whether the viewer at the other end of `socket` spoke (a WebSocket close: a page sends nothing
/// else) or hung up within `timeout_ms`.
bool viewer_spoke_or_left(tcp::socket& socket, int timeout_ms) {
  pollfd watched{.fd = socket.native_handle(), .events = POLLIN, .revents = 0};
  return ::poll(&watched, 1, timeout_ms) != 0;
}

/// GET /ws: the session's messages, one binary WebSocket message each, through a Subscribe call.
/// With ?wait_s=S a session that does not exist yet is waited for, up to S seconds: the page is
/// told once ({"waiting": NAME, "wait_s": S}), and `probe` looks for the session without a call (so
/// a waiting page costs neither calls nor log lines) until it exists, the viewer leaves, lipsyncd
/// shuts down, or S seconds pass (then NOT_FOUND saying so).
FollowOutcome follow_session(websocket::stream<tcp::socket&>& ws, tcp::socket& socket, v1::LipSync::Stub& stub,
                             const QueryParameters& query, const std::optional<std::string>& authorization,
                             const SessionProbe& probe, grpc::ClientContext& context,
                             const std::atomic<bool>& closing) {
  FollowOutcome outcome;
  const auto close_with = [&](grpc::StatusCode code, const std::string& message) {
    close_with_status(ws, code, message);
  };
  const auto session = query.find("session");
  if (session == query.end() || session->second.empty()) {
    close_with(grpc::StatusCode::INVALID_ARGUMENT, "the WebSocket needs a session: /ws?session=NAME");
    return outcome;
  }
  const auto start = query.find("start");
  v1::SubscribeRequest request;
  request.set_session(session->second);
  if (start == query.end() || start->second == "beginning") {
    request.set_start(v1::SubscribeRequest::START_FROM_BEGINNING);
  } else if (start->second == "now") {
    request.set_start(v1::SubscribeRequest::START_FROM_NOW);
  } else {
    close_with(grpc::StatusCode::INVALID_ARGUMENT, "start: expected 'beginning' or 'now', got '" + start->second + "'");
    return outcome;
  }
  int wait_s = 0;
  if (const auto wait = query.find("wait_s"); wait != query.end()) {
    const std::string& text = wait->second;
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), wait_s);
    if (error != std::errc() || end != text.data() + text.size() || wait_s < 0 || wait_s > kMaxSessionWaitS) {
      close_with(grpc::StatusCode::INVALID_ARGUMENT, "wait_s: expected whole seconds from 0 to " +
                                                         std::to_string(kMaxSessionWaitS) + ", got '" + text + "'");
      return outcome;
    }
  }
  if (wait_s > 0 && probe) {
    const std::string_view key = authorization ? std::string_view(*authorization) : std::string_view();
    const auto look = [&] { return probe(authorization ? &key : nullptr, session->second); };
    grpc::Status found = look();
    if (found.error_code() == grpc::StatusCode::NOT_FOUND) {
      const auto since = std::chrono::steady_clock::now();
      const auto give_up = since + std::chrono::seconds(wait_s);
      beast::error_code error;
      ws.text(true);
      ws.write(boost::asio::buffer(nlohmann::json{{"waiting", session->second}, {"wait_s", wait_s}}.dump()), error);
      while (!error && found.error_code() == grpc::StatusCode::NOT_FOUND) {
        outcome.waited =
            std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - since);
        if (closing) {
          close_going_away(ws);
          return outcome;
        }
        if (std::chrono::steady_clock::now() >= give_up) {
          outcome.gave_up_after_s = wait_s;
          close_with(grpc::StatusCode::NOT_FOUND, "session '" + session->second + "' did not start within " +
                                                      std::to_string(wait_s) + " s (" + found.error_message() + ")");
          return outcome;
        }
        if (viewer_spoke_or_left(socket, kSessionPollIntervalMs)) {
          beast::flat_buffer ignored;
          ws.read(ignored, error);  // its close, answered by Beast
          return outcome;
        }
        found = look();
      }
      if (error) return outcome;
    }
  }

  ws.binary(true);
  auto reader = stub.Subscribe(&context, request);
  v1::TrackMessage message;
  std::string bytes;
  bool client_gone = false;
  while (reader->Read(&message)) {
    if (client_gone) continue;  // draining after the cancel
    message.SerializeToString(&bytes);
    beast::error_code error;
    ws.write(boost::asio::buffer(bytes), error);
    if (error) {
      client_gone = true;
      context.TryCancel();
    }
  }
  const grpc::Status status = reader->Finish();
  if (client_gone) return outcome;
  beast::error_code ignored;
  if (status.ok()) {
    ws.close(websocket::close_reason(websocket::close_code::normal, "OK"), ignored);
  } else if (closing) {
    close_going_away(ws);
  } else {
    close_with(status.error_code(), status.error_message());
  }
  return outcome;
}

/// POST /sessions: one Animate call with the pasted text; answers once the session is complete.
Response quick_try(const Request& request, v1::LipSync::Stub& stub, const QuickTry& plan,
                   grpc::ClientContext& context) {
  auto stream = stub.Animate(&context);
  std::uint64_t frames = 0;
  std::thread reader([&] {
    v1::TrackMessage message;
    while (stream->Read(&message)) {
      if (message.has_summary()) frames = message.summary().frames();
    }
  });
  v1::AnimateRequest message;
  *message.mutable_settings() = plan.settings;
  stream->Write(message);
  message.Clear();
  for (const v1::Phoneme& phoneme : plan.phonemes) *message.mutable_phonemes()->add_phonemes() = phoneme;
  stream->Write(message);
  message.Clear();
  message.mutable_end();
  stream->Write(message);
  stream->WritesDone();
  reader.join();
  const grpc::Status status = stream->Finish();
  if (!status.ok()) {
    return text_response(request, http_status(status.error_code()),
                         error_json(code_name(status.error_code()), status.error_message()), "application/json");
  }
  const std::string& session = plan.settings.session();
  const nlohmann::json body = {{"session", session},
                               {"phonemes", plan.phonemes.size()},
                               {"frames", frames},
                               {"utterance_zero_us", plan.settings.media_clock().utterance_zero_us()},
                               {"view", "/view?session=" + session}};
  return text_response(request, http::status::ok, body.dump(), "application/json");
}

/// POST /sessions?speak=1: one Speak call with the posted text; answers once it has spoken.
Response quick_speak(const Request& request, v1::LipSync::Stub& stub, const v1::SpeakRequest& speak,
                     grpc::ClientContext& context) {
  auto reader = stub.Speak(&context, speak);
  v1::SpeakResponse message;
  std::uint64_t frames = 0, phonemes = 0;
  std::int64_t audio_us = 0;
  while (reader->Read(&message)) {
    if (message.has_header()) {
      phonemes = static_cast<std::uint64_t>(message.header().phonemes_size());
      audio_us = message.header().audio_duration_us();
    }
    if (message.has_summary()) frames = message.summary().track().frames();
  }
  const grpc::Status status = reader->Finish();
  if (!status.ok()) {
    return text_response(request, http_status(status.error_code()),
                         error_json(code_name(status.error_code()), status.error_message()), "application/json");
  }
  const std::string& session = speak.settings().session();
  const nlohmann::json body = {{"session", session},
                               {"phonemes", phonemes},
                               {"frames", frames},
                               {"audio_duration_us", audio_us},
                               {"audio", "/audio?session=" + session},
                               {"utterance_zero_us", speak.settings().media_clock().utterance_zero_us()},
                               {"view", "/view?session=" + session}};
  return text_response(request, http::status::ok, body.dump(), "application/json");
}

Response serve_asset(const Request& request, const std::string& path) {
  const std::string wanted = path == "/" ? "/view" : path;
  for (const WebAsset& asset : web_assets()) {
    if (asset.path != wanted) continue;
    if (request.method() != http::verb::get && request.method() != http::verb::head) {
      Response response = text_response(request, http::status::method_not_allowed, path + ": only GET\n");
      response.set(http::field::allow, "GET, HEAD");
      return response;
    }
    Response response = text_response(request, http::status::ok, std::string(asset.body), asset.content_type);
    if (request.method() == http::verb::head) response.body().clear();
    return response;
  }
  return text_response(request, http::status::not_found,
                       "lipsyncd: no such page: " + path + " (the viewer is at /view?session=NAME)\n");
}

/// Where close() finds a connection's running call, for a route's CallRegistration.
struct CallSlot {
  std::mutex& mutex;
  grpc::ClientContext*& call;
  const std::atomic<bool>& closing;
};

/// A route's call on the in-process channel: the caller's key forwarded, registered for close().
struct ViewerCall {
  ViewerCall(const Request& request, const QueryParameters& query, const CallSlot& slot)
      : registration(slot.mutex, slot.call, context, slot.closing) {
    forward_api_key(request, query, context);
  }
  grpc::ClientContext context;
  CallRegistration registration;
};

/// /ws?session=NAME: upgrades to a WebSocket and follows the session until it ends or the viewer
/// closes. Returns whether the connection stays open for another request (only after answering a
/// request that is not an upgrade).
bool serve_websocket(tcp::socket& socket, const Request& request, const QueryParameters& query, v1::LipSync::Stub& stub,
                     const SessionProbe& probe, const CallSlot& slot) {
  beast::error_code error;
  if (!websocket::is_upgrade(request)) {
    http::write(socket, text_response(request, http::status::upgrade_required, "/ws is a WebSocket: open it as one\n"),
                error);
    return !error;
  }
  const std::string peer = socket.remote_endpoint(error).address().to_string();
  websocket::stream<tcp::socket&> ws(socket);
  if (!accept_upgrade(ws, request)) return false;
  ViewerCall call(request, query, slot);
  if (!call.registration.admitted) {
    close_going_away(ws);
    return false;
  }
  const auto started = std::chrono::steady_clock::now();
  const FollowOutcome outcome =
      follow_session(ws, socket, stub, query, authorization_value(request, query), probe, call.context, slot.closing);
  spdlog::info(
      "viewer WebSocket end peer={} session='{}' duration_ms={} waited_ms={}{}", peer,
      query.count("session") ? query.at("session") : "",
      std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - started).count(),
      outcome.waited.count(),
      outcome.gave_up_after_s > 0
          ? " (the session did not start within " + std::to_string(outcome.gave_up_after_s) + " s)"
          : std::string());
  return false;
}

/// Paces a page's live voice: the audio received may run at most kMaxPageAudioLeadUs ahead of the
/// time since its first piece, so a page sends as it hears (or plays) the sound, not a file at once.
class PageAudioPace {
 public:
  PageAudioPace(std::uint32_t rate_hz, std::uint32_t channels) : bytes_per_second_(2.0 * rate_hz * channels) {}

  /// Counts `bytes` received now; an empty string, or what is wrong.
  std::string admit(std::size_t bytes) {
    const auto now = std::chrono::steady_clock::now();
    if (total_bytes_ == 0) first_ = now;
    total_bytes_ += bytes;
    const auto audio_us = static_cast<std::int64_t>(static_cast<double>(total_bytes_) / bytes_per_second_ * 1e6);
    const auto elapsed_us = std::chrono::duration_cast<std::chrono::microseconds>(now - first_).count();
    if (audio_us - elapsed_us <= kMaxPageAudioLeadUs) return {};
    return "the page sends audio faster than it is spoken: " + std::to_string(audio_us / 1000) + " ms of audio in " +
           std::to_string(elapsed_us / 1000) + " ms (at most " + std::to_string(kMaxPageAudioLeadUs / 1000) +
           " ms ahead; /listen is for a voice as it is heard: send a file whole with Listen's `recording`)";
  }

 private:
  double bytes_per_second_;
  std::size_t total_bytes_ = 0;
  std::chrono::steady_clock::time_point first_;
};

/// /listen?session=NAME&rate=HZ&...: a live voice from the page. Each binary message is the next
/// piece of 16-bit little-endian PCM, a text message {"end": true} says the voice has ended; the
/// pieces go into one Listen call on the in-process channel (its admission, limits, keys and
/// errors), whose session the page and anyone else follow on /ws. Its TrackMessages are not sent
/// back here: the follower has them. After the end: the text message {"session", "frames",
/// "duration_us", "notes"} and a close with 1000 "OK"; an error: {"code", "message"} and 4000 + the
/// gRPC code, as /ws. A page that goes away before the end cancels the call, so the session's
/// followers see it end with ABORTED, as for a gRPC producer that vanishes.
bool serve_listen(tcp::socket& socket, const Request& request, const QueryParameters& query, v1::LipSync::Stub& stub,
                  const CallSlot& slot) {
  beast::error_code error;
  if (!websocket::is_upgrade(request)) {
    http::write(socket,
                text_response(request, http::status::upgrade_required,
                              "/listen is a WebSocket: open it as one and send 16-bit PCM pieces\n"),
                error);
    return !error;
  }
  const std::string peer = socket.remote_endpoint(error).address().to_string();
  websocket::stream<tcp::socket&> ws(socket);
  ws.read_message_max(4 * kMaxPagePieceBytes);  // beyond it Beast closes with 1009; below, the message names it
  if (!accept_upgrade(ws, request)) return false;
  v1::ListenRequest message;
  try {
    *message.mutable_settings() = plan_page_listen(query, unix_now_us());
  } catch (const QuickTryError& bad) {
    close_with_status(ws, grpc::StatusCode::INVALID_ARGUMENT, bad.what());
    return false;
  }
  const std::string session = message.settings().animation().session();
  PageAudioPace pace(message.settings().sample_rate_hz(), std::max(1U, message.settings().channels()));
  ViewerCall call(request, query, slot);
  if (!call.registration.admitted) {
    close_going_away(ws);
    return false;
  }
  const auto started = std::chrono::steady_clock::now();
  auto stream = stub.Listen(&call.context);
  v1::TrackSummary summary;
  std::thread drain([&] {
    v1::TrackMessage answer;
    while (stream->Read(&answer)) {
      if (answer.has_summary()) summary = answer.summary();
    }
  });
  bool open = stream->Write(message);
  bool ended = false;
  bool page_gone = false;
  grpc::Status refused;
  std::size_t bytes = 0;
  beast::flat_buffer buffer;
  while (open && !ended) {
    buffer.clear();
    ws.read(buffer, error);
    if (error) {
      page_gone = error != websocket::error::message_too_big;
      if (!page_gone) {  // Beast has closed it with 1009; the call ends as refused
        refused = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                               "a piece of more than " + std::to_string(4 * kMaxPagePieceBytes) + " bytes");
      }
      break;
    }
    const std::string_view data(static_cast<const char*>(buffer.data().data()), buffer.size());
    if (ws.got_text()) {
      const nlohmann::json text = nlohmann::json::parse(data, nullptr, false);
      if (!text.is_object() || text.size() != 1 || !text.contains("end") || text["end"] != true) {
        refused = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                               "a text message that is not {\"end\": true}: the voice is sent as binary pieces of "
                               "16-bit PCM, and {\"end\": true} ends it");
        break;
      }
      ended = true;
      message.Clear();
      message.mutable_end();
      open = stream->Write(message);
      break;
    }
    if (data.size() > kMaxPagePieceBytes) {
      refused = grpc::Status(grpc::StatusCode::INVALID_ARGUMENT,
                             "a piece of " + std::to_string(data.size()) + " bytes, more than " +
                                 std::to_string(kMaxPagePieceBytes) +
                                 ": send the voice in smaller pieces (20 ms of 48 kHz mono is 1920 bytes)");
      break;
    }
    if (const std::string too_fast = pace.admit(data.size()); !too_fast.empty()) {
      refused = grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, too_fast);
      break;
    }
    bytes += data.size();
    message.Clear();
    message.mutable_audio()->set_data(data.data(), data.size());
    open = stream->Write(message);
  }
  if (page_gone || !refused.ok()) call.context.TryCancel();
  stream->WritesDone();
  drain.join();
  const grpc::Status status = stream->Finish();
  spdlog::info(
      "viewer listen end peer={} session='{}' duration_ms={} audio_bytes={} status={}{}", peer, session,
      std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - started).count(), bytes,
      code_name(!refused.ok() ? refused.error_code() : status.error_code()),
      page_gone ? " (the page went away before the end)" : "");
  if (page_gone) return false;
  if (!refused.ok()) {
    close_with_status(ws, refused.error_code(), refused.error_message());
  } else if (!status.ok()) {
    if (slot.closing) {
      close_going_away(ws);
    } else {
      close_with_status(ws, status.error_code(), status.error_message());
    }
  } else {
    ws.text(true);
    const nlohmann::json body = {{"session", session},
                                 {"frames", summary.frames()},
                                 {"duration_us", summary.duration_us()},
                                 {"notes", std::vector<std::string>(summary.notes().begin(), summary.notes().end())}};
    ws.write(boost::asio::buffer(body.dump()), error);
    ws.close(websocket::close_reason(websocket::close_code::normal, "OK"), error);
  }
  return false;
}

/// POST /sessions: the quick try (docs/viewer.md): pasted phoneme text animated into a new
/// session, or with ?speak=1 the text spoken; the answer says where to watch it.
Response serve_sessions(const Request& request, const QueryParameters& query, v1::LipSync::Stub& stub,
                        const ModelCatalog& catalog, const CallSlot& slot) {
  if (request.method() != http::verb::post) {
    Response response =
        text_response(request, http::status::method_not_allowed, "/sessions: only POST (the phoneme text)\n");
    response.set(http::field::allow, "POST");
    return response;
  }
  try {
    const auto speak = query.find("speak");
    const bool speaking = speak != query.end() && speak->second == "1";
    if (speak != query.end() && !speaking && speak->second != "0") {
      throw QuickTryError("speak: expected 1 (speak the text with espeak-ng) or 0, got '" + speak->second + "'");
    }
    const QuickTry plan = speaking ? QuickTry{} : plan_quick_try(query, request.body(), catalog, unix_now_us());
    const v1::SpeakRequest spoken =
        speaking ? plan_quick_speak(query, request.body(), unix_now_us()) : v1::SpeakRequest{};
    ViewerCall call(request, query, slot);
    return !call.registration.admitted
               ? text_response(request, http::status::service_unavailable,
                               error_json("UNAVAILABLE", "lipsyncd is shutting down"), "application/json")
           : speaking ? quick_speak(request, stub, spoken, call.context)
                      : quick_try(request, stub, plan, call.context);
  } catch (const InputError& bad) {
    return text_response(request, http::status::bad_request, error_json("INVALID_ARGUMENT", bad.what()),
                         "application/json");
  } catch (const QuickTryError& bad) {
    return text_response(request, http::status::bad_request, error_json("INVALID_ARGUMENT", bad.what()),
                         "application/json");
  }
}

}  // namespace

HttpViewer::HttpViewer(const std::string& host_port, std::shared_ptr<grpc::Channel> service,
                       const ModelCatalog& catalog, SessionAudioLookup session_audio, SessionProbe session_probe)
    : service_(std::move(service)),
      catalog_(catalog),
      session_audio_(std::move(session_audio)),
      session_probe_(std::move(session_probe)),
      acceptor_(io_) {
  const tcp::endpoint endpoint = resolve(io_, host_port, host_);
  beast::error_code error;
  acceptor_.open(endpoint.protocol(), error);
  if (!error) acceptor_.set_option(boost::asio::socket_base::reuse_address(true), error);
  if (!error) acceptor_.bind(endpoint, error);
  if (!error) acceptor_.listen(boost::asio::socket_base::max_listen_connections, error);
  if (error) throw std::runtime_error("--http-listen: cannot listen on " + host_port + ": " + error.message());
  port_ = acceptor_.local_endpoint().port();
  accept_thread_ = std::thread([this] { accept_loop(); });
}

HttpViewer::~HttpViewer() { close(); }

int HttpViewer::port() const { return port_; }

std::string HttpViewer::address() const { return host_ + ":" + std::to_string(port_); }

void HttpViewer::accept_loop() {
  while (!closing_) {
    tcp::socket socket(io_);
    beast::error_code error;
    acceptor_.accept(socket, error);
    if (closing_) break;
    if (error) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));  // e.g. out of descriptors: retry
      continue;
    }
    std::lock_guard lock(mutex_);
    reap_finished_locked();
    auto& connection = *connections_.emplace_back(std::make_unique<Connection>(std::move(socket)));
    connection.thread = std::thread([this, &connection] {
      serve(connection);
      connection.done = true;
    });
  }
}

void HttpViewer::reap_finished_locked() {
  for (auto it = connections_.begin(); it != connections_.end();) {
    if ((*it)->done) {
      (*it)->thread.join();
      it = connections_.erase(it);
    } else {
      ++it;
    }
  }
}

void HttpViewer::serve(Connection& connection) {
  beast::flat_buffer buffer;
  auto stub = v1::LipSync::NewStub(service_);
  for (;;) {
    http::request_parser<http::string_body> parser;
    parser.body_limit(kMaxBodyBytes);
    beast::error_code error;
    http::read(connection.socket, buffer, parser, error);
    if (error == http::error::body_limit) {
      Request too_large;
      auto response = text_response(too_large, http::status::payload_too_large,
                                    "the body is larger than " + std::to_string(kMaxBodyBytes) + " bytes\n");
      response.keep_alive(false);
      http::write(connection.socket, response, error);
      break;
    }
    if (error) break;  // the peer closed, or not HTTP
    Request request = parser.release();
    QueryParameters query;
    std::string path;
    try {
      const beast::string_view target = request.target();
      path = split_request_target(std::string_view(target.data(), target.size()), query);
    } catch (const std::invalid_argument& bad) {
      http::write(connection.socket, text_response(request, http::status::bad_request, std::string(bad.what()) + "\n"),
                  error);
      break;
    }

    const CallSlot slot{connection.call_mutex, connection.call, closing_};
    if (path == "/ws") {
      if (!serve_websocket(connection.socket, request, query, *stub, session_probe_, slot)) break;
      continue;
    }

    if (path == "/listen") {
      if (!serve_listen(connection.socket, request, query, *stub, slot)) break;
      continue;
    }

    if (path == "/audio") {
      if (!serve_audio(connection.socket, request, query, session_audio_)) break;
      continue;
    }

    Response response;
    if (path == "/sessions") {
      response = serve_sessions(request, query, *stub, catalog_, slot);
    } else {
      response = serve_asset(request, path);
    }
    http::write(connection.socket, response, error);
    if (error || !response.keep_alive()) break;
  }
  beast::error_code ignored;
  connection.socket.shutdown(tcp::socket::shutdown_both, ignored);
}

void HttpViewer::close() {
  if (closing_.exchange(true)) return;
  // Wake the blocking accept (shutdown is safe from another thread; close is not).
  ::shutdown(acceptor_.native_handle(), SHUT_RDWR);
  if (accept_thread_.joinable()) accept_thread_.join();
  std::lock_guard lock(mutex_);
  // Running calls first: their followers then say "going away" on their own.
  for (auto& connection : connections_) {
    std::lock_guard call_lock(connection->call_mutex);
    if (connection->call) connection->call->TryCancel();
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(1);
  for (auto& connection : connections_) {
    while (!connection->done && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  // Then every connection still open (idle keep-alive, or a peer that does not read).
  for (auto& connection : connections_) {
    if (!connection->done) ::shutdown(connection->socket.native_handle(), SHUT_RDWR);
  }
  for (auto& connection : connections_) connection->thread.join();
  connections_.clear();
  beast::error_code ignored;
  acceptor_.close(ignored);
}

}  // namespace lipsync::server
