// ConnectionLedger: the connections lipsyncd's listener handed to gRPC, and
// whether each has carried a call yet.
//
// It exists for one moment, the start of a drain. A balancer (nginx without
// upstream keepalive) opens one connection per call and sends the call right
// after connecting. When the listener closes, a connection the kernel has
// already completed (in the accept backlog, or just handed to gRPC) has its
// call still on the way; the balancer believes it connected, so refusing that
// call, or resetting the connection, fails the client's new session instead of
// sending it to another replica. So during a drain a connection's *first* call
// is still served when the connection was accepted shortly before (or while)
// the listener closed, and the drain waits for such first calls to arrive.
// Calls on connections that already carried one are refused as before.
//
// gRPC names the peer of a connection handed over by fd "fd:N"; fd numbers are
// reused, and each accept overwrites the entry of its number. Peers of another
// form (gRPC's own listener, used with TLS) are never fresh.
#pragma once

#include <chrono>
#include <mutex>
#include <optional>
#include <string_view>
#include <unordered_map>

namespace lipsync::server {

class ConnectionLedger {
 public:
  using Clock = std::chrono::steady_clock;

  /// The listener handed connection `fd` to gRPC at `at`.
  void accepted(int fd, Clock::time_point at);
  /// A call arrived from `peer` (gRPC's peer name). When it is the first call of one of
  /// the listener's connections: the time that connection was accepted. The connection
  /// counts as used from now on.
  std::optional<Clock::time_point> first_call(std::string_view peer);
  /// Whether a connection accepted at or after `since` has not carried a call yet.
  bool awaiting_first_call(Clock::time_point since) const;

 private:
  struct Connection {
    Clock::time_point accepted_at;
    bool carried_call = false;
  };
  mutable std::mutex mutex_;
  std::unordered_map<int, Connection> connections_;
};

}  // namespace lipsync::server
