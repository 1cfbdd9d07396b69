// What the server logs about a call, in one place: a start line, and one access
// line per call when it is done (method, peer, session, tenant, final status as
// the client received it, duration in microseconds, and the call's own figures).
//
// Two formats (--log-format): `text`, spdlog's usual lines
// ("Animate end peer=ipv4:127.0.0.1:5000 session='demo' phonemes=12 ... status=OK"),
// and `json`, one object per line with the fields time (UTC, ISO 8601 with
// microseconds), level, event, method, session, tenant, peer, status, message,
// duration_us and the call's own fields. In json every other log line is an
// object too (event "log", its text in `message`). Client values (session names)
// are written as excerpts (lipsync/excerpt.hpp) in text; json escapes them.
#pragma once

#include <grpcpp/grpcpp.h>
#include <spdlog/common.h>

#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <string_view>

namespace lipsync::server {

struct ServerMetrics;
using Clock = std::chrono::steady_clock;

enum class LogFormat { text, json };

/// Whole microseconds since `since`.
inline std::int64_t microseconds_since(Clock::time_point since) {
  return std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - since).count();
}

/// Sets the format of the default logger's lines (call once the logger exists).
void set_log_format(LogFormat format);

/// The status code's name, with the message unless it is OK.
std::string status_name(const grpc::Status& status);
/// The status code's name alone ("INVALID_ARGUMENT").
const char* code_name(grpc::StatusCode code);

/// What a call that gRPC reported cancelled ended with, as the access line says it: the
/// client cancelled or went away, its deadline passed, or gRPC ended it (a message over
/// --max-message-bytes: the client then got RESOURCE_EXHAUSTED).
grpc::Status cancelled_status();

/// One extra field of a call line: a number or a text.
struct LogField {
  LogField(std::string_view key_in, std::int64_t value) : key(key_in), number(value), is_number(true) {}
  LogField(std::string_view key_in, std::uint64_t value)
      : key(key_in), number(static_cast<std::int64_t>(value)), is_number(true) {}
  LogField(std::string_view key_in, std::string_view value) : key(key_in), text(value) {}
  std::string_view key;
  std::string_view text;
  std::int64_t number = 0;
  bool is_number = false;
};

/// What every line about one call says. Made when the call starts: the peer is read
/// then (gRPC no longer knows it once the call is over).
class CallLog {
 public:
  /// With `metrics`, the access line also counts the call (lipsyncd_calls_total, _refusals_total).
  CallLog(const char* method, grpc::CallbackServerContext& context, ServerMetrics* metrics = nullptr);

  void set_session(std::string session) { session_ = std::move(session); }
  /// The caller's tenant (tenants.hpp), once authenticated: in the lines and the metrics' labels.
  void set_tenant(std::string tenant) { tenant_ = std::move(tenant); }
  const std::string& session() const { return session_; }
  const std::string& peer() const { return peer_; }
  const char* method() const { return method_; }
  Clock::time_point started() const { return started_; }

  /// "Animate start": logged at info.
  void started_line(std::initializer_list<LogField> fields = {}) const;
  /// The access line: the call is done with `status` (info; warn for refused calls).
  void ended(const grpc::Status& status, std::initializer_list<LogField> fields = {}) const;
  /// Any other line about the call (`event` names it: "cancelled", "stalled").
  void line(spdlog::level::level_enum level, std::string_view event, std::string_view message) const;

 private:
  void write(spdlog::level::level_enum level, std::string_view event, const grpc::Status* status,
             std::string_view message, std::initializer_list<LogField> fields) const;

  const char* method_;
  ServerMetrics* metrics_;
  std::string peer_;
  std::string session_;
  std::string tenant_;  // empty on an open server or before authentication
  Clock::time_point started_;
};

}  // namespace lipsync::server
