// CallError, the one exception of the client library: what was being done, where, the gRPC
// status code by its name in the specification (lipsync::grpc_status_code_name, the table the
// server uses too) and the server's message.
#include <utility>

#include "lipsync/client/animation_client.hpp"
#include "lipsync/grpc_status_name.hpp"

namespace lipsync::client {

std::string_view status_code_name(grpc::StatusCode code) { return grpc_status_code_name(code); }

CallError::CallError(std::string_view context, grpc::StatusCode code, std::string message)
    : std::runtime_error(std::string(context) + " failed: " + std::string(status_code_name(code)) +
                         (message.empty() ? std::string() : ": " + message)),
      code_(code),
      message_(std::move(message)) {}

}  // namespace lipsync::client
