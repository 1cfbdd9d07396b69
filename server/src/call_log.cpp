// Call lines in text or JSON (call_log.hpp). JSON lines are built here: a call
// line reaches spdlog as its JSON members behind a marker byte, and the JSON
// formatter puts time and level in front; any other line becomes an object with
// event "log". Strings go through nlohmann::json's escaping (invalid UTF-8
// replaced), so every line parses.
#include "call_log.hpp"

#include <spdlog/pattern_formatter.h>
#include <spdlog/spdlog.h>

#include <array>
#include <atomic>
#include <charconv>
#include <cstddef>
#include <ctime>
#include <memory>
#include <nlohmann/json.hpp>

#include "lipsync/excerpt.hpp"
#include "lipsync/grpc_status_name.hpp"
#include "metrics.hpp"
#include "transport/listener.hpp"

namespace lipsync::server {
namespace {

constexpr char kJsonMembers = '\x1f';  // a payload that is already JSON members
std::atomic<LogFormat> g_format{LogFormat::text};

std::string json_string(std::string_view text) {
  return nlohmann::json(std::string(text)).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

void append(spdlog::memory_buf_t& out, std::string_view text) { out.append(text.data(), text.data() + text.size()); }

/// "2026-11-23T16:30:00.123456Z"
std::string utc_time(spdlog::log_clock::time_point time) {
  const auto micros = std::chrono::duration_cast<std::chrono::microseconds>(time.time_since_epoch()).count();
  const std::time_t seconds = static_cast<std::time_t>(micros / 1'000'000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  std::array<char, 40> text{};
  const auto length = std::strftime(text.data(), text.size(), "%Y-%m-%dT%H:%M:%S", &utc);
  std::array<char, 16> fraction{};
  std::snprintf(fraction.data(), fraction.size(), ".%06lldZ", static_cast<long long>(micros % 1'000'000));
  return std::string(text.data(), length) + fraction.data();
}

class JsonFormatter final : public spdlog::formatter {
 public:
  void format(const spdlog::details::log_msg& msg, spdlog::memory_buf_t& dest) override {
    const std::string_view payload(msg.payload.data(), msg.payload.size());
    append(dest, "{\"time\":\"" + utc_time(msg.time) + "\",\"level\":\"");
    const auto level = spdlog::level::to_string_view(msg.level);
    append(dest, std::string_view(level.data(), level.size()));
    append(dest, "\",");
    if (!payload.empty() && payload.front() == kJsonMembers) {
      append(dest, payload.substr(1));
    } else {
      append(dest, "\"event\":\"log\",\"message\":" + json_string(payload));
    }
    append(dest, "}\n");
  }
  std::unique_ptr<spdlog::formatter> clone() const override { return std::make_unique<JsonFormatter>(); }
};

/// The session as a log shows it: whole if a valid session name could be that long, else an excerpt.
std::string logged_session(const std::string& session) { return session.size() <= 256 ? session : excerpt(session); }

/// The peer as gRPC names it, resolved to the client's address for connections lipsyncd accepted itself.
std::string resolved_peer(const std::string& peer) {
  int fd = -1;
  if (peer.rfind("fd:", 0) == 0 && std::from_chars(peer.data() + 3, peer.data() + peer.size(), fd).ec == std::errc()) {
    return connection_peer(fd);
  }
  return peer;
}

}  // namespace

void set_log_format(LogFormat format) {
  g_format = format;
  if (format == LogFormat::json) {
    spdlog::set_formatter(std::make_unique<JsonFormatter>());
  } else {
    spdlog::set_formatter(std::make_unique<spdlog::pattern_formatter>());
  }
}

// The names are string literals, so their views end in a NUL.
const char* code_name(grpc::StatusCode code) { return grpc_status_code_name(code).data(); }

std::string status_name(const grpc::Status& status) {
  std::string name = code_name(status.error_code());
  if (!status.ok()) name += " (" + status.error_message() + ")";
  return name;
}

grpc::Status cancelled_status() {
  return {grpc::StatusCode::CANCELLED,
          "cancelled: by the client, by its deadline, or by gRPC (e.g. a message over --max-message-bytes)"};
}

CallLog::CallLog(const char* method, grpc::CallbackServerContext& context, ServerMetrics* metrics)
    : method_(method), metrics_(metrics), peer_(resolved_peer(context.peer())), started_(Clock::now()) {}

void CallLog::started_line(std::initializer_list<LogField> fields) const {
  write(spdlog::level::info, "start", nullptr, {}, fields);
}

void CallLog::ended(const grpc::Status& status, std::initializer_list<LogField> fields) const {
  write(spdlog::level::info, "end", &status, {}, fields);
  if (metrics_) {
    const LabelValues labels = {method_, code_name(status.error_code()), tenant_};
    metrics_->calls.with(labels).add();
    if (!status.ok() && status.error_code() != grpc::StatusCode::CANCELLED) metrics_->refusals.with(labels).add();
  }
}

void CallLog::line(spdlog::level::level_enum level, std::string_view event, std::string_view message) const {
  write(level, event, nullptr, message, {});
}

void CallLog::write(spdlog::level::level_enum level, std::string_view event, const grpc::Status* status,
                    std::string_view message, std::initializer_list<LogField> fields) const {
  if (!spdlog::should_log(level)) return;
  const auto duration_us = microseconds_since(started_);
  std::string line;
  if (g_format == LogFormat::json) {
    line += kJsonMembers;
    line += "\"event\":" + json_string(std::string(method_) + "." + std::string(event));
    line += ",\"method\":" + json_string(method_);
    line += ",\"session\":" + json_string(logged_session(session_));
    line += ",\"tenant\":" + json_string(tenant_);
    line += ",\"peer\":" + json_string(peer_);
    for (const LogField& field : fields) {
      line += "," + json_string(field.key) + ":";
      line += field.is_number ? std::to_string(field.number) : json_string(field.text);
    }
    if (status) {
      line += ",\"status\":" + json_string(code_name(status->error_code()));
      line += ",\"message\":" + json_string(status->error_message());
      line += ",\"duration_us\":" + std::to_string(duration_us);
    } else if (!message.empty()) {
      line += ",\"message\":" + json_string(message);
    }
  } else {
    line = std::string(method_) + " " + std::string(event) + " peer=" + peer_;
    if (!session_.empty()) line += " session=" + excerpt(session_);
    if (!tenant_.empty()) line += " tenant=" + excerpt(tenant_);
    for (const LogField& field : fields) {
      line += " " + std::string(field.key) + "=";
      line += field.is_number ? std::to_string(field.number) : std::string(field.text);
    }
    if (status) {
      std::array<char, 32> ms{};
      std::snprintf(ms.data(), ms.size(), "%.1f", static_cast<double>(duration_us) / 1000.0);
      line += " duration_ms=" + std::string(ms.data()) + " status=" + status_name(*status);
    }
    if (!message.empty()) line += ": " + std::string(message);
  }
  spdlog::log(level, "{}", line);
}

}  // namespace lipsync::server
