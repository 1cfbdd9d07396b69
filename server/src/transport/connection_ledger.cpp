#include "connection_ledger.hpp"

#include <charconv>

namespace lipsync::server {
namespace {

/// N of a gRPC peer named "fd:N"; -1 for any other peer.
int peer_fd(std::string_view peer) {
  constexpr std::string_view kPrefix = "fd:";
  if (peer.substr(0, kPrefix.size()) != kPrefix) return -1;
  int fd = -1;
  const char* begin = peer.data() + kPrefix.size();
  const char* end = peer.data() + peer.size();
  const auto [ptr, error] = std::from_chars(begin, end, fd);
  return error == std::errc() && ptr == end ? fd : -1;
}

}  // namespace

void ConnectionLedger::accepted(int fd, Clock::time_point at) {
  std::lock_guard lock(mutex_);
  connections_[fd] = Connection{at, false};
}

std::optional<ConnectionLedger::Clock::time_point> ConnectionLedger::first_call(std::string_view peer) {
  const int fd = peer_fd(peer);
  if (fd < 0) return std::nullopt;
  std::lock_guard lock(mutex_);
  const auto found = connections_.find(fd);
  if (found == connections_.end() || found->second.carried_call) return std::nullopt;
  found->second.carried_call = true;
  return found->second.accepted_at;
}

bool ConnectionLedger::awaiting_first_call(Clock::time_point since) const {
  std::lock_guard lock(mutex_);
  for (const auto& [fd, connection] : connections_) {
    if (!connection.carried_call && connection.accepted_at >= since) return true;
  }
  return false;
}

}  // namespace lipsync::server
