// Session routing: a session lives in the memory of the one replica that runs
// its Animate stream, so every call about it must reach that replica. Clients
// send the session name twice: in the request body, and as the metadata
// `x-lipsync-session`, an HTTP/2 header a load balancer can hash on (nginx
// `hash $http_x_lipsync_session consistent`, Envoy's ring hash; docs/deploy.md).
// SessionRouting checks that the two agree and words the NOT_FOUND that a
// misrouted Subscribe gets, naming the replica that answered, so that a
// balancer misconfiguration shows in one look.
#pragma once

#include <grpcpp/server_context.h>
#include <grpcpp/support/status.h>

#include <cstdint>
#include <mutex>
#include <string>

namespace lipsync::server {

class SessionRouting {
 public:
  static constexpr const char* kMetadataKey = "x-lipsync-session";

  /// `name` as set by --replica-name, or "" for "<host name> (<listen address>)".
  explicit SessionRouting(std::string name, const std::string& listen);

  /// Once the port is bound (port 0 picks one): the default name shows the real address.
  void set_bound_address(const std::string& address);
  std::string replica_name() const;

  /// OK when the call carries no `x-lipsync-session` or it equals `body_session`;
  /// INVALID_ARGUMENT naming both otherwise.
  grpc::Status check_metadata(const grpc::CallbackServerContext& context, const std::string& body_session) const;

  /// The NOT_FOUND of a Subscribe to a session this replica does not hold.
  grpc::Status not_held(const std::string& session, std::int64_t retention_ms) const;

 private:
  const bool named_;  // set by --replica-name: never replaced
  mutable std::mutex mutex_;
  std::string name_;
};

}  // namespace lipsync::server
