// A minimal gRPC client over one HTTP/2 connection, written on nghttp2 for
// `lipsync loadtest`, so that one generator core can drive thousands of
// real-time sessions.
//
// Why not gRPC's own client: measured with `perf` at 2,000 real-time sessions
// (docs/performance.md, "The load generator"), gRPC's C++
// client kept 0.73 of the generator's core busy, 58 % of it in the kernel: a
// wake-up of one of gRPC's threads and a write(2) for nearly every message.
// Here every stream of the connection lives on the caller's Asio thread;
// requests queued while that thread runs its handlers leave in one write, and
// one read(2) brings whatever the server sent on every stream.
//
// What it speaks is the part of gRPC's HTTP/2 protocol (gRPC's
// doc/PROTOCOL-HTTP2.md) that streaming calls need: a POST on the method's
// path with `content-type: application/grpc` and `te: trailers`, messages
// framed as one flag byte (0: not compressed) and a 4-byte big-endian length,
// then the status in `grpc-status` / `grpc-message` (in the trailers, or in
// the only HEADERS of a "trailers-only" answer). It sends no compressed
// messages and accepts none, and it has no TLS: loopback load tests only.
//
// Threading: everything, including the handlers, runs on the io_context's
// thread; none of it may be called from another thread.
#pragma once

#include <nghttp2/nghttp2.h>

#include <boost/asio/generic/stream_protocol.hpp>
#include <boost/asio/io_context.hpp>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

namespace lipsync::cli {

/// How a call ended: gRPC's status code (0 = OK) and message.
struct H2CallStatus {
  int code = 0;
  std::string message;
};

/// Gets one gRPC message's bytes (without the 5-byte prefix), valid during the call of the
/// handler only. Returns false if they are not what the call expects: the call then ends with
/// INTERNAL.
using H2MessageHandler = std::function<bool(std::span<const std::uint8_t>)>;
using H2DoneHandler = std::function<void(const H2CallStatus&)>;

/// `payload` with gRPC's message prefix: flag 0 (not compressed), 4-byte big-endian length.
std::string grpc_frame(std::string_view payload);

class H2GrpcConnection;

/// A call on an H2GrpcConnection, as its caller holds it. Destroying it before
/// the call ended cancels the call; its handlers are not called after that.
class H2Call {
 public:
  H2Call(H2GrpcConnection& connection, std::int32_t stream_id) : connection_(&connection), stream_id_(stream_id) {}
  ~H2Call();
  H2Call(const H2Call&) = delete;
  H2Call& operator=(const H2Call&) = delete;

  /// Queues `framed` (one or more messages with their prefixes) to be sent.
  /// False once the call has ended or was finished: then nothing is sent.
  bool send(std::string_view framed);
  /// Sends what is queued, then closes the request side (END_STREAM).
  void finish();
  /// Resets the stream (RST_STREAM CANCEL); the done handler gets CANCELLED.
  void cancel();

 private:
  H2GrpcConnection* connection_;
  std::int32_t stream_id_;
};

class H2GrpcConnection {
 public:
  /// Connects to `address` (HOST:PORT, [V6]:PORT or unix:PATH) and waits for
  /// the server's HTTP/2 SETTINGS. `headers` go with every call (e.g.
  /// authorization). Throws std::runtime_error saying what failed (the caller names the address).
  H2GrpcConnection(boost::asio::io_context& io, const std::string& address,
                   std::vector<std::pair<std::string, std::string>> headers, std::chrono::milliseconds connect_timeout);
  ~H2GrpcConnection();
  H2GrpcConnection(const H2GrpcConnection&) = delete;
  H2GrpcConnection& operator=(const H2GrpcConnection&) = delete;

  /// Starts a call of `path` (/package.Service/Method) with `metadata`
  /// besides the connection's headers, and `first` (framed) as its first
  /// request bytes. `on_message` gets each response message, `on_done` the
  /// status, once.
  std::unique_ptr<H2Call> start(std::string_view path, const std::vector<std::pair<std::string, std::string>>& metadata,
                                std::string first, H2MessageHandler on_message, H2DoneHandler on_done);

  /// Closes the socket: open calls end with UNAVAILABLE; the io_context has no more work from it.
  void close();

 private:
  friend class H2Call;
  struct Stream;

  void start_reading();
  void schedule_flush();
  void flush();
  void fail_all(const std::string& why);
  void deliver(std::int32_t id, const std::uint8_t* data, std::size_t length);
  Stream* find(std::int32_t id);

  // H2Call's operations.
  bool send(std::int32_t id, std::string_view framed);
  void finish(std::int32_t id);
  void cancel(std::int32_t id);
  void detach(std::int32_t id);

  // nghttp2's callbacks (user_data is the connection).
  static ssize_t read_request(nghttp2_session*, std::int32_t id, std::uint8_t* buffer, std::size_t length,
                              std::uint32_t* flags, nghttp2_data_source* source, void* user_data);
  static int on_header(nghttp2_session*, const nghttp2_frame* frame, const std::uint8_t* name, std::size_t name_length,
                       const std::uint8_t* value, std::size_t value_length, std::uint8_t flags, void* user_data);
  static int on_data(nghttp2_session*, std::uint8_t flags, std::int32_t id, const std::uint8_t* data,
                     std::size_t length, void* user_data);
  static int on_frame(nghttp2_session*, const nghttp2_frame* frame, void* user_data);
  static int on_close(nghttp2_session*, std::int32_t id, std::uint32_t error_code, void* user_data);

  boost::asio::io_context& io_;
  boost::asio::generic::stream_protocol::socket socket_;
  std::string address_;
  std::vector<std::pair<std::string, std::string>> headers_;
  std::unique_ptr<nghttp2_session, void (*)(nghttp2_session*)> session_{nullptr, &nghttp2_session_del};
  std::unordered_map<std::int32_t, std::unique_ptr<Stream>> streams_;
  std::vector<std::uint8_t> read_buffer_;
  std::string authority_;
  std::string writing_;  ///< bytes of the write in flight
  bool write_in_flight_ = false;
  bool flush_posted_ = false;
  bool settings_received_ = false;
  bool closed_ = false;
  std::int32_t next_refused_id_ = -1;  ///< calls started on a closed connection get negative ids
  std::shared_ptr<bool> alive_ = std::make_shared<bool>(true);  ///< false once destroyed: late handlers return
};

}  // namespace lipsync::cli
