// Listener: lipsyncd's own listening sockets, whose accepted connections are
// handed to gRPC (AddInsecureChannelFromFd).
//
// Owning the listener lets a drain stop new connections at once while the
// connections already open stay untouched until their calls end. gRPC's own
// Shutdown closes its listener only together with sending GOAWAY on every
// connection, and gRPC 1.51 then closes a connection right after its last
// stream, racing the stream's final frames: behind nginx, streams that had
// finished on the server reached the client as RST_STREAM INTERNAL_ERROR
// ("upstream prematurely closed connection"). With the listener closed first,
// a balancer's new connection is refused and goes to another replica.
// Connections the kernel completed before the close (the accept backlog) are
// accepted and handed over, not reset: their client believes it connected.
#pragma once

#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace grpc {
class Server;
}

namespace lipsync::server {

class ConnectionLedger;

/// The address of the client connected on `fd` ("ipv4:10.0.0.7:51234"), "fd:N" if it is gone.
/// gRPC names the peer of a connection handed to it by fd "fd:N"; the call logs name it by this.
std::string connection_peer(int fd);

class Listener {
 public:
  /// Binds and listens on `host_port` ("127.0.0.1:0", "0.0.0.0:50051", "[::]:50051",
  /// "localhost:6000": every address the host resolves to). Throws std::runtime_error
  /// saying why it cannot.
  explicit Listener(const std::string& host_port);
  ~Listener();
  Listener(const Listener&) = delete;
  Listener& operator=(const Listener&) = delete;

  /// The port bound (the one picked when asked for port 0).
  int port() const { return port_; }

  /// Accepts connections on a thread of its own and hands them to `server`, recording
  /// each in `connections`.
  void start(grpc::Server& server, ConnectionLedger& connections);
  /// Stops accepting and closes the listening sockets (new connections are refused);
  /// connections already completed by the kernel are handed over first. Idempotent.
  void close();

 private:
  /// Accepts one connection from `socket` and hands it over; false when none is waiting.
  bool accept_one(int socket);

  grpc::Server* server_ = nullptr;
  ConnectionLedger* connections_ = nullptr;
  std::vector<int> sockets_;
  int wake_fd_ = -1;  // an eventfd that wakes the accepting thread to stop
  int port_ = 0;
  std::thread acceptor_;
};

}  // namespace lipsync::server
