// What every call of the client library shares: on the way out, its deadline and the session
// metadata a balancer routes on; on the way back, a status other than OK, or an answer that breaks
// the protocol, as a CallError (animation_client.hpp).
#pragma once

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <string>
#include <string_view>

#include "lipsync/client/animation_client.hpp"

namespace lipsync::client::detail {

inline std::chrono::system_clock::time_point deadline_after(std::chrono::milliseconds timeout) {
  return std::chrono::system_clock::now() + timeout;
}

// The session travels twice: in the body, and as metadata that a balancer can route on (the
// replica holding a session is chosen by hashing it, docs/deploy.md). lipsyncd checks they agree.
inline void add_session_metadata(grpc::ClientContext& context, const std::string& session) {
  if (!session.empty()) context.AddMetadata(std::string(kSessionMetadataKey), session);
}

inline void throw_unless_ok(const grpc::Status& status, std::string_view context) {
  if (!status.ok()) throw CallError(context, status.error_code(), status.error_message());
}

inline CallError protocol_error(const std::string& message) {
  return CallError("reading the server's answer", grpc::StatusCode::INTERNAL, message);
}

}  // namespace lipsync::client::detail
