#include "session_routing.hpp"

#include <unistd.h>

#include <array>

#include "lipsync/excerpt.hpp"

namespace lipsync::server {
namespace {

std::string host_name() {
  std::array<char, 256> name{};
  if (::gethostname(name.data(), name.size() - 1) != 0) return "unknown host";
  return name.data();
}

std::string default_name(const std::string& address) { return host_name() + " (" + address + ")"; }

}  // namespace

SessionRouting::SessionRouting(std::string name, const std::string& listen)
    : named_(!name.empty()), name_(named_ ? std::move(name) : default_name(listen)) {}

void SessionRouting::set_bound_address(const std::string& address) {
  if (named_) return;
  std::lock_guard lock(mutex_);
  name_ = default_name(address);
}

std::string SessionRouting::replica_name() const {
  std::lock_guard lock(mutex_);
  return name_;
}

grpc::Status SessionRouting::check_metadata(const grpc::CallbackServerContext& context,
                                            const std::string& body_session) const {
  const auto& metadata = context.client_metadata();
  const auto found = metadata.find(kMetadataKey);
  if (found == metadata.end()) return grpc::Status::OK;
  const std::string routed(found->second.data(), found->second.size());
  if (routed == body_session) return grpc::Status::OK;
  return {grpc::StatusCode::INVALID_ARGUMENT,
          std::string("metadata ") + kMetadataKey + " " + excerpt(routed) + " differs from the request's session " +
              excerpt(body_session) + ": the balancer routes on the metadata, so both must name the same session"};
}

grpc::Status SessionRouting::not_held(const std::string& session, std::int64_t retention_ms) const {
  return {grpc::StatusCode::NOT_FOUND,
          "no session named " + excerpt(session) + " at replica " + replica_name() +
              ": it is not held here (never opened on this replica, or ended more than " +
              std::to_string(retention_ms) +
              " ms ago). A session lives on the replica that runs its Animate stream; behind a load "
              "balancer every call must be routed by its x-lipsync-session metadata (consistent hash, "
              "docs/deploy.md)"};
}

}  // namespace lipsync::server
