// GET /metrics over HTTP/1.1 with Boost.Beast (metrics_http.hpp): asynchronous
// accept, read and write on one io_context thread, each connection with a 5 s
// expiry.
#include "metrics_http.hpp"

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <chrono>
#include <stdexcept>
#include <thread>

namespace lipsync::server {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using tcp = asio::ip::tcp;

constexpr auto kConnectionTimeout = std::chrono::seconds(5);

class HttpExchange : public std::enable_shared_from_this<HttpExchange> {
 public:
  HttpExchange(tcp::socket socket, const std::function<std::string()>& exposition)
      : stream_(std::move(socket)), exposition_(exposition) {}

  void start() {
    stream_.expires_after(kConnectionTimeout);
    http::async_read(stream_, buffer_, request_,
                     [self = shared_from_this()](beast::error_code error, std::size_t) { self->on_read(error); });
  }

 private:
  void on_read(beast::error_code error) {
    if (error) return;
    response_.version(request_.version());
    response_.keep_alive(false);
    response_.set(http::field::server, "lipsyncd");
    if (request_.method() != http::verb::get && request_.method() != http::verb::head) {
      reply(http::status::method_not_allowed, "text/plain", "only GET\n");
    } else if (request_.target() != "/metrics") {
      reply(http::status::not_found, "text/plain", "metrics are at /metrics\n");
    } else {
      reply(http::status::ok, "text/plain; version=0.0.4; charset=utf-8",
            request_.method() == http::verb::head ? std::string() : exposition_());
    }
    http::async_write(stream_, response_, [self = shared_from_this()](beast::error_code, std::size_t) {
      beast::error_code ignored;
      self->stream_.socket().shutdown(tcp::socket::shutdown_send, ignored);
    });
  }

  void reply(http::status status, const char* content_type, std::string body) {
    response_.result(status);
    response_.set(http::field::content_type, content_type);
    response_.body() = std::move(body);
    response_.prepare_payload();
  }

  beast::tcp_stream stream_;
  const std::function<std::string()>& exposition_;
  beast::flat_buffer buffer_;
  http::request<http::string_body> request_;
  http::response<http::string_body> response_;
};

}  // namespace

struct MetricsEndpoint::Impl {
  asio::io_context io{1};
  tcp::acceptor acceptor{io};
  std::function<std::string()> exposition;
  std::string host;
  std::thread thread;

  void accept() {
    acceptor.async_accept(asio::make_strand(io), [this](beast::error_code error, tcp::socket socket) {
      if (error == asio::error::operation_aborted) return;
      if (!error) std::make_shared<HttpExchange>(std::move(socket), exposition)->start();
      accept();
    });
  }
};

MetricsEndpoint::MetricsEndpoint(const std::string& host_port, std::function<std::string()> exposition)
    : impl_(std::make_unique<Impl>()) {
  impl_->exposition = std::move(exposition);
  const auto colon = host_port.rfind(':');
  impl_->host = host_port.substr(0, colon);
  std::string host = impl_->host;
  if (host.size() > 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  beast::error_code error;
  tcp::resolver resolver(impl_->io);
  const auto found = resolver.resolve(host, host_port.substr(colon + 1), error);
  if (error || found.empty()) {
    throw std::runtime_error("--metrics-listen: cannot resolve " + host_port + ": " + error.message());
  }
  const tcp::endpoint endpoint = *found.begin();
  impl_->acceptor.open(endpoint.protocol(), error);
  if (!error) impl_->acceptor.set_option(asio::socket_base::reuse_address(true), error);
  if (!error) impl_->acceptor.bind(endpoint, error);
  if (!error) impl_->acceptor.listen(asio::socket_base::max_listen_connections, error);
  if (error) throw std::runtime_error("--metrics-listen: cannot listen on " + host_port + ": " + error.message());
  impl_->accept();
  impl_->thread = std::thread([impl = impl_.get()] { impl->io.run(); });
}

MetricsEndpoint::~MetricsEndpoint() {
  impl_->io.stop();
  if (impl_->thread.joinable()) impl_->thread.join();
}

std::string MetricsEndpoint::address() const {
  return impl_->host + ":" + std::to_string(impl_->acceptor.local_endpoint().port());
}

}  // namespace lipsync::server
