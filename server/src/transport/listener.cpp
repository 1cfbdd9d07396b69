#include "listener.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <grpcpp/server.h>
#include <grpcpp/server_posix.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "transport/connection_ledger.hpp"

namespace lipsync::server {
namespace {

constexpr int kBacklog = 1024;

int bound_port(int socket) {
  sockaddr_storage address{};
  socklen_t size = sizeof(address);
  if (::getsockname(socket, reinterpret_cast<sockaddr*>(&address), &size) != 0) return 0;
  if (address.ss_family == AF_INET6) return ntohs(reinterpret_cast<sockaddr_in6*>(&address)->sin6_port);
  return ntohs(reinterpret_cast<sockaddr_in*>(&address)->sin_port);
}

void set_port(sockaddr* address, int port) {
  if (address->sa_family == AF_INET6) {
    reinterpret_cast<sockaddr_in6*>(address)->sin6_port = htons(static_cast<std::uint16_t>(port));
  } else {
    reinterpret_cast<sockaddr_in*>(address)->sin_port = htons(static_cast<std::uint16_t>(port));
  }
}

std::string peer_name(const sockaddr_storage& peer) {
  char text[INET6_ADDRSTRLEN] = "?";
  if (peer.ss_family == AF_INET6) {
    const auto& v6 = reinterpret_cast<const sockaddr_in6&>(peer);
    ::inet_ntop(AF_INET6, &v6.sin6_addr, text, sizeof(text));
    return "ipv6:[" + std::string(text) + "]:" + std::to_string(ntohs(v6.sin6_port));
  }
  const auto& v4 = reinterpret_cast<const sockaddr_in&>(peer);
  ::inet_ntop(AF_INET, &v4.sin_addr, text, sizeof(text));
  return "ipv4:" + std::string(text) + ":" + std::to_string(ntohs(v4.sin_port));
}

}  // namespace

std::string connection_peer(int fd) {
  sockaddr_storage peer{};
  socklen_t peer_size = sizeof(peer);
  if (::getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &peer_size) != 0) return "fd:" + std::to_string(fd);
  return peer_name(peer);
}

Listener::Listener(const std::string& host_port) {
  const auto colon = host_port.rfind(':');
  std::string host = host_port.substr(0, colon);
  const std::string port = host_port.substr(colon + 1);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
  addrinfo* found = nullptr;
  if (const int error = ::getaddrinfo(host.empty() ? nullptr : host.c_str(), port.c_str(), &hints, &found)) {
    throw std::runtime_error("cannot listen on " + host_port + ": " + ::gai_strerror(error));
  }
  std::string last_error = "no address";
  bool has_ipv4 = false;
  for (addrinfo* address = found; address != nullptr; address = address->ai_next) {
    has_ipv4 = has_ipv4 || address->ai_family == AF_INET;
  }
  for (addrinfo* address = found; address != nullptr; address = address->ai_next) {
    // With port 0, every address gets the port the first one picked (as gRPC does).
    if (port_ != 0) set_port(address->ai_addr, port_);
    const int fd = ::socket(address->ai_family, address->ai_socktype | SOCK_CLOEXEC, address->ai_protocol);
    if (fd < 0) continue;
    const int on = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &on, sizeof(on));
    // "[::]" alone serves IPv4 too; beside an IPv4 address of its own, IPv6 stays IPv6.
    if (address->ai_family == AF_INET6 && has_ipv4) ::setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &on, sizeof(on));
    if (::bind(fd, address->ai_addr, address->ai_addrlen) != 0 || ::listen(fd, kBacklog) != 0) {
      last_error = std::strerror(errno);
      ::close(fd);
      continue;
    }
    if (port_ == 0) port_ = bound_port(fd);
    sockets_.push_back(fd);
  }
  ::freeaddrinfo(found);
  if (sockets_.empty()) throw std::runtime_error("cannot listen on " + host_port + ": " + last_error);
  wake_fd_ = ::eventfd(0, EFD_CLOEXEC);
}

Listener::~Listener() {
  close();
  if (wake_fd_ >= 0) ::close(wake_fd_);
}

void Listener::start(grpc::Server& server, ConnectionLedger& connections) {
  server_ = &server;
  connections_ = &connections;
  acceptor_ = std::thread([this] {
    std::vector<pollfd> polled;
    for (const int fd : sockets_) polled.push_back({fd, POLLIN, 0});
    polled.push_back({wake_fd_, POLLIN, 0});
    while (true) {
      if (::poll(polled.data(), polled.size(), -1) < 0 && errno != EINTR) return;
      if (polled.back().revents != 0) return;  // close()
      for (std::size_t i = 0; i + 1 < polled.size(); ++i) {
        if ((polled[i].revents & POLLIN) != 0) accept_one(polled[i].fd);
      }
    }
  });
}

bool Listener::accept_one(int socket) {
  sockaddr_storage peer{};
  socklen_t peer_size = sizeof(peer);
  const int connection =
      ::accept4(socket, reinterpret_cast<sockaddr*>(&peer), &peer_size, SOCK_NONBLOCK | SOCK_CLOEXEC);
  if (connection < 0) {
    const int error = errno;
    if (error == EINTR || error == ECONNABORTED) return true;  // others may still be waiting
    if (error != EAGAIN && error != EWOULDBLOCK) {
      spdlog::warn("accept failed: {}", std::strerror(error));
      std::this_thread::sleep_for(std::chrono::milliseconds(10));  // e.g. out of file descriptors
    }
    return false;
  }
  const int on = 1;
  ::setsockopt(connection, IPPROTO_TCP, TCP_NODELAY, &on, sizeof(on));
  // gRPC names such a connection's peer "fd:N" in the call logs: this line says who it is.
  spdlog::debug("connection fd:{} from {}", connection, peer_name(peer));
  connections_->accepted(connection, std::chrono::steady_clock::now());
  grpc::AddInsecureChannelFromFd(server_, connection);
  return true;
}

void Listener::close() {
  if (acceptor_.joinable()) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const auto written = ::write(wake_fd_, &one, sizeof(one));
    acceptor_.join();
    // Closing a listening socket resets the connections in its backlog, which their
    // clients (a balancer) already count as connected: take them in first.
    for (const int fd : sockets_) {
      ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
      while (accept_one(fd)) {
      }
    }
  }
  for (const int fd : sockets_) ::close(fd);
  sockets_.clear();
}

}  // namespace lipsync::server
