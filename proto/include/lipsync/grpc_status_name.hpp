// The names of gRPC's status codes as the gRPC specification spells them
// ("INVALID_ARGUMENT"), for every place lipsyncd and its clients write one: the
// server's logs, metrics labels and viewer errors, the client library's errors,
// the load generator's report. One table, so that they always agree.
#pragma once

#include <grpcpp/support/status.h>

#include <array>
#include <cstddef>
#include <string_view>

namespace lipsync {

/// The code's name; a code outside the specification's 0..16 is "UNKNOWN", as
/// gRPC itself treats it.
constexpr std::string_view grpc_status_code_name(grpc::StatusCode code) {
  constexpr std::array<std::string_view, 17> kNames = {
      "OK",        "CANCELLED",      "UNKNOWN",           "INVALID_ARGUMENT",   "DEADLINE_EXCEEDED",
      "NOT_FOUND", "ALREADY_EXISTS", "PERMISSION_DENIED", "RESOURCE_EXHAUSTED", "FAILED_PRECONDITION",
      "ABORTED",   "OUT_OF_RANGE",   "UNIMPLEMENTED",     "INTERNAL",           "UNAVAILABLE",
      "DATA_LOSS", "UNAUTHENTICATED"};
  const auto index = static_cast<std::size_t>(code);
  return index < kNames.size() ? kNames[index] : "UNKNOWN";
}

}  // namespace lipsync
