// The gRPC status code names (grpc::StatusCode has no to_string), in code order.
#include "call_log.hpp"

#include <array>
#include <cstddef>

namespace lipsync::server {

std::string status_name(const grpc::Status& status) {
  static constexpr std::array<const char*, 17> kNames = {
      "OK", "CANCELLED", "UNKNOWN", "INVALID_ARGUMENT", "DEADLINE_EXCEEDED", "NOT_FOUND",
      "ALREADY_EXISTS", "PERMISSION_DENIED", "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION", "ABORTED",
      "OUT_OF_RANGE", "UNIMPLEMENTED", "INTERNAL", "UNAVAILABLE", "DATA_LOSS", "UNAUTHENTICATED"};
  const auto code = static_cast<std::size_t>(status.error_code());
  std::string name = code < kNames.size() ? kNames[code] : std::to_string(code);
  if (!status.ok()) name += " (" + status.error_message() + ")";
  return name;
}

double elapsed_ms(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
}

}  // namespace lipsync::server
