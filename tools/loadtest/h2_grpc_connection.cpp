// The HTTP/2 side of the load generator's gRPC client: nghttp2 does the
// framing, flow control and HPACK; this file moves bytes between it and one
// socket on an Asio thread and turns streams into gRPC calls.
//
// Writes: every operation that gives nghttp2 something to send (a request, a
// message, a half-close, a window update after a read) only schedules a
// flush; the flush runs once after the handlers that are ready now, and sends
// all that nghttp2 has in one write. While a write is in flight, new frames
// wait in nghttp2's queue for the next flush.
//
// Requests: a stream's outgoing bytes are a string the data source reads
// from; when it is empty the source defers (NGHTTP2_ERR_DEFERRED) and a later
// send resumes it.
//
// Responses: DATA is cut into gRPC messages (5-byte prefix, then the bytes);
// a message wholly inside one DATA chunk is handed over in place, others are
// gathered first. The status comes from `grpc-status` and `grpc-message`
// (percent-encoded), or from the HTTP status or the RST_STREAM code when the
// server sent none, mapped as gRPC's doc/http-grpc-status-mapping.md says.
#include "h2_grpc_connection.hpp"

#include <grpcpp/support/status_code_enum.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>

#include <algorithm>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/local/stream_protocol.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/write.hpp>
#include <cstring>
#include <optional>
#include <stdexcept>

namespace lipsync::cli {

namespace asio = boost::asio;

namespace {

// gRPC's status codes used here, as the int the connection reports.
constexpr int kCancelled = grpc::StatusCode::CANCELLED;
constexpr int kUnknown = grpc::StatusCode::UNKNOWN;
constexpr int kResourceExhausted = grpc::StatusCode::RESOURCE_EXHAUSTED;
constexpr int kPermissionDenied = grpc::StatusCode::PERMISSION_DENIED;
constexpr int kUnimplemented = grpc::StatusCode::UNIMPLEMENTED;
constexpr int kInternal = grpc::StatusCode::INTERNAL;
constexpr int kUnavailable = grpc::StatusCode::UNAVAILABLE;
constexpr int kUnauthenticated = grpc::StatusCode::UNAUTHENTICATED;

/// Larger messages than this end the call (lipsyncd's own limit is far below).
constexpr std::size_t kMaxMessageBytes = std::size_t{64} << 20;
constexpr std::size_t kReadBufferBytes = std::size_t{256} << 10;
/// Receive windows: large, so that the server never waits for a window update.
constexpr std::uint32_t kStreamWindow = std::uint32_t{1} << 24;
constexpr std::int32_t kConnectionWindow = std::int32_t{1} << 30;

std::uint32_t read_be32(const std::uint8_t* bytes) {
  return (std::uint32_t{bytes[0]} << 24) | (std::uint32_t{bytes[1]} << 16) | (std::uint32_t{bytes[2]} << 8) |
         std::uint32_t{bytes[3]};
}

/// grpc-message is percent-encoded (gRPC's PROTOCOL-HTTP2.md).
std::string percent_decode(std::string_view text) {
  std::string decoded;
  decoded.reserve(text.size());
  const auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '%' && i + 2 < text.size() && hex(text[i + 1]) >= 0 && hex(text[i + 2]) >= 0) {
      decoded += static_cast<char>(hex(text[i + 1]) * 16 + hex(text[i + 2]));
      i += 2;
    } else {
      decoded += text[i];
    }
  }
  return decoded;
}

/// The gRPC code of an HTTP status other than 200 (gRPC's http-grpc-status-mapping.md).
int code_of_http_status(int status) {
  switch (status) {
    case 400:
      return kInternal;
    case 401:
      return kUnauthenticated;
    case 403:
      return kPermissionDenied;
    case 404:
      return kUnimplemented;
    case 429:
    case 502:
    case 503:
    case 504:
      return kUnavailable;
    default:
      return kUnknown;
  }
}

/// The gRPC code of a stream the server reset without a status.
int code_of_reset(std::uint32_t http2_error) {
  switch (http2_error) {
    case NGHTTP2_REFUSED_STREAM:
      return kUnavailable;
    case NGHTTP2_CANCEL:
      return kCancelled;
    case NGHTTP2_ENHANCE_YOUR_CALM:
      return kResourceExhausted;
    case NGHTTP2_INADEQUATE_SECURITY:
      return kPermissionDenied;
    default:
      return kInternal;
  }
}

nghttp2_nv header(const std::string& name, const std::string& value) {
  return {reinterpret_cast<std::uint8_t*>(const_cast<char*>(name.data())),
          reinterpret_cast<std::uint8_t*>(const_cast<char*>(value.data())), name.size(), value.size(),
          NGHTTP2_NV_FLAG_NONE};
}

/// The endpoint of HOST:PORT, [V6]:PORT or unix:PATH.
asio::generic::stream_protocol::endpoint endpoint_of(asio::io_context& io, const std::string& address) {
  if (address.rfind("unix:", 0) == 0) return asio::local::stream_protocol::endpoint(address.substr(5));
  const std::size_t colon = address.rfind(':');
  if (colon == std::string::npos) throw std::runtime_error("'" + address + "' has no port (HOST:PORT)");
  std::string host = address.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  asio::ip::tcp::resolver resolver(io);
  boost::system::error_code error;
  const auto results = resolver.resolve(host, address.substr(colon + 1), error);
  if (error || results.empty()) {
    throw std::runtime_error("cannot resolve '" + address + "': " + (error ? error.message() : "no address"));
  }
  return results.begin()->endpoint();
}

}  // namespace

std::string grpc_frame(std::string_view payload) {
  std::string framed(5 + payload.size(), '\0');
  const auto length = static_cast<std::uint32_t>(payload.size());
  framed[1] = static_cast<char>(length >> 24);
  framed[2] = static_cast<char>(length >> 16);
  framed[3] = static_cast<char>(length >> 8);
  framed[4] = static_cast<char>(length);
  std::memcpy(framed.data() + 5, payload.data(), payload.size());
  return framed;
}

struct H2GrpcConnection::Stream {
  H2MessageHandler on_message;
  H2DoneHandler on_done;
  std::string outgoing;    ///< request bytes not yet given to nghttp2
  std::size_t taken = 0;   ///< of outgoing, given to nghttp2
  bool deferred = false;   ///< the data source waits for bytes (resume on send)
  bool finishing = false;  ///< END_STREAM after outgoing
  bool cancelled = false;
  std::string incoming;  ///< a response message not yet whole
  int http_status = 0;
  std::optional<int> grpc_status;
  std::string grpc_message;
  std::optional<std::string> failure;  ///< what made us end the call (an INTERNAL error)
};

// --- H2Call -----------------------------------------------------------------------------------

H2Call::~H2Call() { connection_->detach(stream_id_); }
bool H2Call::send(std::string_view framed) { return connection_->send(stream_id_, framed); }
void H2Call::finish() { connection_->finish(stream_id_); }
void H2Call::cancel() { connection_->cancel(stream_id_); }

// --- connection ---------------------------------------------------------------------------------

H2GrpcConnection::H2GrpcConnection(asio::io_context& io, const std::string& address,
                                   std::vector<std::pair<std::string, std::string>> headers,
                                   std::chrono::milliseconds connect_timeout)
    : io_(io), socket_(io), address_(address), headers_(std::move(headers)), read_buffer_(kReadBufferBytes) {
  authority_ = address.rfind("unix:", 0) == 0 ? "localhost" : address;
  boost::system::error_code error;
  socket_.connect(endpoint_of(io, address), error);
  if (error) throw std::runtime_error(error.message() + " (is lipsyncd running there? see --server)");
  if (address.rfind("unix:", 0) != 0) {
    // Without it Nagle's algorithm holds a small write until the last one is acknowledged:
    // up to the peer's delayed-ACK time (40 ms) added to a phoneme's latency.
    const int on = 1;
    ::setsockopt(socket_.native_handle(), IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
  }

  nghttp2_session_callbacks* callbacks = nullptr;
  nghttp2_session_callbacks_new(&callbacks);
  nghttp2_session_callbacks_set_on_header_callback(callbacks, &H2GrpcConnection::on_header);
  nghttp2_session_callbacks_set_on_data_chunk_recv_callback(callbacks, &H2GrpcConnection::on_data);
  nghttp2_session_callbacks_set_on_frame_recv_callback(callbacks, &H2GrpcConnection::on_frame);
  nghttp2_session_callbacks_set_on_stream_close_callback(callbacks, &H2GrpcConnection::on_close);
  nghttp2_session* session = nullptr;
  const int created = nghttp2_session_client_new(&session, callbacks, this);
  nghttp2_session_callbacks_del(callbacks);
  if (created != 0) throw std::runtime_error(nghttp2_strerror(created));
  session_.reset(session);
  const nghttp2_settings_entry settings[] = {{NGHTTP2_SETTINGS_ENABLE_PUSH, 0},
                                             {NGHTTP2_SETTINGS_INITIAL_WINDOW_SIZE, kStreamWindow}};
  nghttp2_submit_settings(session_.get(), NGHTTP2_FLAG_NONE, settings, std::size(settings));
  nghttp2_session_set_local_window_size(session_.get(), NGHTTP2_FLAG_NONE, 0, kConnectionWindow);

  // The preface and our settings, then wait (blocking, bounded) for the server's settings: a
  // server that is not HTTP/2 in plaintext (one with TLS, say) is found here, not on the first call.
  const std::string not_http2 =
      "it did not answer as a plaintext HTTP/2 (gRPC) server; if it uses TLS, run loadtest with --client grpc "
      "and --tls/--ca";
  for (;;) {
    const std::uint8_t* data = nullptr;
    const ssize_t length = nghttp2_session_mem_send(session_.get(), &data);
    if (length <= 0) break;
    asio::write(socket_, asio::buffer(data, static_cast<std::size_t>(length)), error);
    if (error) throw std::runtime_error("the server closed the connection (" + error.message() + "); " + not_http2);
  }
  const auto deadline = std::chrono::steady_clock::now() + connect_timeout;
  while (!settings_received_) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    pollfd ready{socket_.native_handle(), POLLIN, 0};
    if (left.count() <= 0 || ::poll(&ready, 1, static_cast<int>(left.count())) <= 0) {
      throw std::runtime_error("no HTTP/2 settings within " + std::to_string(connect_timeout.count()) + " ms; " +
                               not_http2);
    }
    const std::size_t length = socket_.read_some(asio::buffer(read_buffer_), error);
    if (error) throw std::runtime_error("the server closed the connection (" + error.message() + "); " + not_http2);
    if (nghttp2_session_mem_recv(session_.get(), read_buffer_.data(), length) < 0) throw std::runtime_error(not_http2);
  }
  start_reading();
  schedule_flush();
}

H2GrpcConnection::~H2GrpcConnection() {
  *alive_ = false;
  boost::system::error_code ignored;
  socket_.close(ignored);
}

H2GrpcConnection::Stream* H2GrpcConnection::find(std::int32_t id) {
  const auto found = streams_.find(id);
  return found == streams_.end() ? nullptr : found->second.get();
}

std::unique_ptr<H2Call> H2GrpcConnection::start(std::string_view path,
                                                const std::vector<std::pair<std::string, std::string>>& metadata,
                                                std::string first, H2MessageHandler on_message, H2DoneHandler on_done) {
  auto stream = std::make_unique<Stream>();
  stream->on_message = std::move(on_message);
  stream->on_done = std::move(on_done);
  stream->outgoing = std::move(first);
  std::int32_t id = -1;
  if (!closed_) {
    static const std::string kMethod = ":method", kPost = "POST", kScheme = ":scheme", kHttp = "http", kPath = ":path",
                             kAuthority = ":authority", kContentType = "content-type", kGrpc = "application/grpc",
                             kTe = "te", kTrailers = "trailers", kUserAgent = "user-agent", kAgent = "lipsync-loadtest";
    const std::string path_text(path);
    std::vector<nghttp2_nv> fields = {
        header(kMethod, kPost),      header(kScheme, kHttp), header(kPath, path_text),  header(kAuthority, authority_),
        header(kContentType, kGrpc), header(kTe, kTrailers), header(kUserAgent, kAgent)};
    for (const auto& [name, value] : headers_) fields.push_back(header(name, value));
    for (const auto& [name, value] : metadata) fields.push_back(header(name, value));
    nghttp2_data_provider source{};
    source.read_callback = &H2GrpcConnection::read_request;
    id = nghttp2_submit_request(session_.get(), nullptr, fields.data(), fields.size(), &source, nullptr);
  }
  if (id < 0) {
    // Not started (the connection is closed, or out of stream ids): the call ends with
    // UNAVAILABLE after start returns, as any other call's end is reported.
    const std::string why = closed_ ? "the connection to " + address_ + " is closed"
                                    : "HTTP/2 could not start a stream: " + std::string(nghttp2_strerror(id));
    id = next_refused_id_--;
    streams_.emplace(id, std::move(stream));
    asio::post(io_, [this, alive = alive_, id, why] {
      if (!*alive) return;
      const auto found = streams_.find(id);
      if (found == streams_.end()) return;
      const std::unique_ptr<Stream> ended = std::move(found->second);
      streams_.erase(found);
      ended->on_done({kUnavailable, why});
    });
    return std::make_unique<H2Call>(*this, id);
  }
  streams_.emplace(id, std::move(stream));
  schedule_flush();
  return std::make_unique<H2Call>(*this, id);
}

bool H2GrpcConnection::send(std::int32_t id, std::string_view framed) {
  Stream* stream = find(id);
  if (stream == nullptr || stream->finishing || stream->cancelled || id < 0) return false;
  stream->outgoing.append(framed);
  if (stream->deferred) {
    stream->deferred = false;
    nghttp2_session_resume_data(session_.get(), id);
  }
  schedule_flush();
  return true;
}

void H2GrpcConnection::finish(std::int32_t id) {
  Stream* stream = find(id);
  if (stream == nullptr || stream->finishing || stream->cancelled || id < 0) return;
  stream->finishing = true;
  if (stream->deferred) {
    stream->deferred = false;
    nghttp2_session_resume_data(session_.get(), id);
  }
  schedule_flush();
}

void H2GrpcConnection::cancel(std::int32_t id) {
  Stream* stream = find(id);
  if (stream == nullptr || stream->cancelled || id < 0) return;
  stream->cancelled = true;
  nghttp2_submit_rst_stream(session_.get(), NGHTTP2_FLAG_NONE, id, NGHTTP2_CANCEL);
  schedule_flush();
}

void H2GrpcConnection::detach(std::int32_t id) {
  const auto found = streams_.find(id);
  if (found == streams_.end()) return;  // ended already
  const bool open = id > 0 && !found->second->cancelled && !closed_;
  streams_.erase(found);
  if (open) {
    nghttp2_submit_rst_stream(session_.get(), NGHTTP2_FLAG_NONE, id, NGHTTP2_CANCEL);
    schedule_flush();
  }
}

void H2GrpcConnection::close() {
  if (closed_) return;
  fail_all("the load test closed the connection to " + address_);
}

void H2GrpcConnection::fail_all(const std::string& why) {
  closed_ = true;
  boost::system::error_code ignored;
  socket_.close(ignored);
  std::unordered_map<std::int32_t, std::unique_ptr<Stream>> ended;
  ended.swap(streams_);
  for (auto& [id, stream] : ended) stream->on_done({kUnavailable, why});
}

// --- I/O ------------------------------------------------------------------------------------------

void H2GrpcConnection::start_reading() {
  socket_.async_read_some(
      asio::buffer(read_buffer_), [this, alive = alive_](const boost::system::error_code& error, std::size_t length) {
        if (!*alive || closed_) return;
        if (error) {
          fail_all("the connection to " + address_ + " was lost: " + error.message());
          return;
        }
        const ssize_t used = nghttp2_session_mem_recv(session_.get(), read_buffer_.data(), length);
        if (closed_) return;  // a handler closed the connection
        if (used < 0) {
          fail_all("HTTP/2 error on the connection to " + address_ + ": " + nghttp2_strerror(static_cast<int>(used)));
          return;
        }
        schedule_flush();  // window updates, acknowledgements
        start_reading();
      });
}

void H2GrpcConnection::schedule_flush() {
  if (flush_posted_ || closed_) return;
  flush_posted_ = true;
  asio::post(io_, [this, alive = alive_] {
    if (!*alive) return;
    flush_posted_ = false;
    flush();
  });
}

void H2GrpcConnection::flush() {
  if (closed_ || write_in_flight_) return;  // the write's completion flushes again
  for (;;) {
    const std::uint8_t* data = nullptr;
    const ssize_t length = nghttp2_session_mem_send(session_.get(), &data);
    if (length < 0) {
      fail_all("HTTP/2 error on the connection to " + address_ + ": " + nghttp2_strerror(static_cast<int>(length)));
      return;
    }
    if (length == 0) break;
    writing_.append(reinterpret_cast<const char*>(data), static_cast<std::size_t>(length));
  }
  if (writing_.empty()) return;
  write_in_flight_ = true;
  asio::async_write(socket_, asio::buffer(writing_),
                    [this, alive = alive_](const boost::system::error_code& error, std::size_t) {
                      if (!*alive) return;
                      write_in_flight_ = false;
                      writing_.clear();
                      if (closed_) return;
                      if (error) {
                        fail_all("writing to " + address_ + " failed: " + error.message());
                        return;
                      }
                      flush();
                    });
}

// --- nghttp2's callbacks ----------------------------------------------------------------------------

ssize_t H2GrpcConnection::read_request(nghttp2_session*, std::int32_t id, std::uint8_t* buffer, std::size_t length,
                                       std::uint32_t* flags, nghttp2_data_source*, void* user_data) {
  auto& self = *static_cast<H2GrpcConnection*>(user_data);
  Stream* stream = self.find(id);
  if (stream == nullptr) {  // detached: its RST_STREAM follows
    *flags |= NGHTTP2_DATA_FLAG_EOF;
    return 0;
  }
  const std::size_t left = stream->outgoing.size() - stream->taken;
  if (left == 0) {
    stream->outgoing.clear();
    stream->taken = 0;
    if (stream->finishing) {
      *flags |= NGHTTP2_DATA_FLAG_EOF;
      return 0;
    }
    stream->deferred = true;
    return NGHTTP2_ERR_DEFERRED;
  }
  const std::size_t taken = std::min(left, length);
  std::memcpy(buffer, stream->outgoing.data() + stream->taken, taken);
  stream->taken += taken;
  if (stream->taken == stream->outgoing.size()) {
    stream->outgoing.clear();
    stream->taken = 0;
    if (stream->finishing) *flags |= NGHTTP2_DATA_FLAG_EOF;
  }
  return static_cast<ssize_t>(taken);
}

int H2GrpcConnection::on_header(nghttp2_session*, const nghttp2_frame* frame, const std::uint8_t* name,
                                std::size_t name_length, const std::uint8_t* value, std::size_t value_length,
                                std::uint8_t, void* user_data) {
  if (frame->hd.type != NGHTTP2_HEADERS) return 0;
  auto& self = *static_cast<H2GrpcConnection*>(user_data);
  Stream* stream = self.find(frame->hd.stream_id);
  if (stream == nullptr) return 0;
  const std::string_view key(reinterpret_cast<const char*>(name), name_length);
  const std::string_view text(reinterpret_cast<const char*>(value), value_length);
  if (key == ":status") {
    stream->http_status = std::atoi(std::string(text).c_str());
  } else if (key == "grpc-status") {
    stream->grpc_status = std::atoi(std::string(text).c_str());
  } else if (key == "grpc-message") {
    stream->grpc_message = percent_decode(text);
  }
  return 0;
}

void H2GrpcConnection::deliver(std::int32_t id, const std::uint8_t* data, std::size_t length) {
  static const std::string kUnparsable = "the server sent a message that is not the method's response type";
  Stream* stream = find(id);
  const auto fail = [&](std::string why) {
    stream->failure = std::move(why);
    stream->incoming.clear();
    cancel(id);
  };
  // Whole messages at the start of the chunk, while nothing is gathered, are handed over in place.
  while (stream != nullptr && stream->incoming.empty() && !stream->cancelled && length >= 5) {
    const std::size_t size = read_be32(data + 1);
    if (data[0] != 0) return fail("the server sent a compressed message, which the load test did not ask for");
    if (size > kMaxMessageBytes) return fail("the server sent a message of " + std::to_string(size) + " bytes");
    if (length < 5 + size) break;
    if (!stream->on_message(std::span<const std::uint8_t>(data + 5, size))) return fail(kUnparsable);
    data += 5 + size;
    length -= 5 + size;
    stream = find(id);  // the handler may have ended the call
  }
  if (stream == nullptr || stream->cancelled || length == 0) return;
  stream->incoming.append(reinterpret_cast<const char*>(data), length);
  std::size_t used = 0;
  while (stream->incoming.size() - used >= 5) {
    const auto* bytes = reinterpret_cast<const std::uint8_t*>(stream->incoming.data()) + used;
    const std::size_t size = read_be32(bytes + 1);
    if (bytes[0] != 0) return fail("the server sent a compressed message, which the load test did not ask for");
    if (size > kMaxMessageBytes) return fail("the server sent a message of " + std::to_string(size) + " bytes");
    if (stream->incoming.size() - used < 5 + size) break;
    if (!stream->on_message(std::span<const std::uint8_t>(bytes + 5, size))) return fail(kUnparsable);
    used += 5 + size;
    stream = find(id);
    if (stream == nullptr || stream->cancelled) return;
  }
  stream->incoming.erase(0, used);
}

int H2GrpcConnection::on_data(nghttp2_session*, std::uint8_t, std::int32_t id, const std::uint8_t* data,
                              std::size_t length, void* user_data) {
  static_cast<H2GrpcConnection*>(user_data)->deliver(id, data, length);
  return 0;
}

int H2GrpcConnection::on_frame(nghttp2_session*, const nghttp2_frame* frame, void* user_data) {
  if (frame->hd.type == NGHTTP2_SETTINGS && (frame->hd.flags & NGHTTP2_FLAG_ACK) == 0) {
    static_cast<H2GrpcConnection*>(user_data)->settings_received_ = true;
  }
  return 0;
}

int H2GrpcConnection::on_close(nghttp2_session*, std::int32_t id, std::uint32_t error_code, void* user_data) {
  auto& self = *static_cast<H2GrpcConnection*>(user_data);
  const auto found = self.streams_.find(id);
  if (found == self.streams_.end()) return 0;  // detached
  const std::unique_ptr<Stream> stream = std::move(found->second);
  self.streams_.erase(found);
  H2CallStatus status;
  if (stream->failure) {
    status = {kInternal, *stream->failure};
  } else if (stream->cancelled) {
    status = {kCancelled, "cancelled by the load test"};
  } else if (stream->grpc_status) {
    status = {*stream->grpc_status, stream->grpc_message};
  } else if (stream->http_status != 0 && stream->http_status != 200) {
    status = {code_of_http_status(stream->http_status),
              "HTTP status " + std::to_string(stream->http_status) + " without a grpc-status"};
  } else if (error_code != NGHTTP2_NO_ERROR) {
    status = {code_of_reset(error_code),
              "the server reset the stream (HTTP/2 " + std::string(nghttp2_http2_strerror(error_code)) + ")"};
  } else {
    status = {kInternal, "the stream ended without a grpc-status"};
  }
  stream->on_done(status);
  return 0;
}

}  // namespace lipsync::cli
