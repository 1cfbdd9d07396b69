// What the server logs about a call: its status by name ("INVALID_ARGUMENT
// (settings.fps: ...)") and how long it ran.
#pragma once

#include <chrono>
#include <string>

#include <grpcpp/support/status.h>

namespace lipsync::server {

using Clock = std::chrono::steady_clock;

/// The status code's name, with the message unless it is OK.
std::string status_name(const grpc::Status& status);

/// Milliseconds since `since`.
double elapsed_ms(Clock::time_point since);

}  // namespace lipsync::server
