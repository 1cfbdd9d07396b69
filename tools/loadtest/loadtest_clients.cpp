// The load test's two clients (loadtest_clients.hpp): adapters from LoadCall
// to the client library's calls (grpc) and to H2GrpcConnection's (h2).
#include "loadtest_clients.hpp"

#include <stdexcept>
#include <utility>

#include "h2_grpc_connection.hpp"

namespace lipsync::cli {

namespace {

namespace v1 = client::v1;

constexpr std::string_view kAnimatePath = "/lipsync.v1.LipSync/Animate";
constexpr std::string_view kSubscribePath = "/lipsync.v1.LipSync/Subscribe";

// --- grpc: the client library ---------------------------------------------------------------------

class LibraryAnimateCall final : public LoadCall {
 public:
  LibraryAnimateCall(std::unique_ptr<client::AnimateCall> call, const UtteranceRequests& requests)
      : call_(std::move(call)), requests_(requests) {}
  bool send_phoneme(std::size_t index) override { return call_->send({requests_.phonemes[index]}); }
  void end() override { call_->end(); }
  void cancel() override { call_->cancel(); }

 private:
  std::unique_ptr<client::AnimateCall> call_;
  const UtteranceRequests& requests_;
};

class LibrarySubscribeCall final : public LoadCall {
 public:
  explicit LibrarySubscribeCall(std::unique_ptr<client::SubscribeCall> call) : call_(std::move(call)) {}
  bool send_phoneme(std::size_t) override { return false; }
  void end() override {}
  void cancel() override { call_->cancel(); }

 private:
  std::unique_ptr<client::SubscribeCall> call_;
};

class LibraryClient final : public LoadClient {
 public:
  LibraryClient(const std::string& address, const client::ClientOptions& options, int connections) {
    for (int c = 0; c < connections; ++c) {
      clients_.push_back(std::make_unique<client::AnimationClient>(address, options));
      clients_.back()->wait_connected();
    }
  }
  std::size_t connections() const override { return clients_.size(); }
  std::unique_ptr<LoadCall> animate(std::size_t connection, const v1::AnimationSettings& settings,
                                    const UtteranceRequests& requests, client::MessageHandler on_message,
                                    client::DoneHandler on_done) override {
    return std::make_unique<LibraryAnimateCall>(
        clients_[connection]->start_animate(settings, std::move(on_message), std::move(on_done)), requests);
  }
  std::unique_ptr<LoadCall> subscribe(std::size_t connection, const std::string& session,
                                      client::MessageHandler on_message, client::DoneHandler on_done) override {
    return std::make_unique<LibrarySubscribeCall>(clients_[connection]->start_subscribe(
        session, v1::SubscribeRequest::START_FROM_BEGINNING, std::move(on_message), std::move(on_done)));
  }
  void close() override {}

 private:
  std::vector<std::unique_ptr<client::AnimationClient>> clients_;
};

// --- h2: the generator's own HTTP/2 client ---------------------------------------------------------

class H2LoadCall final : public LoadCall {
 public:
  H2LoadCall(std::unique_ptr<H2Call> call, const UtteranceRequests* requests)
      : call_(std::move(call)), requests_(requests) {}
  bool send_phoneme(std::size_t index) override {
    return requests_ != nullptr && call_->send(requests_->framed[index]);
  }
  void end() override {
    if (requests_ != nullptr) call_->send(requests_->framed.back());
    call_->finish();
  }
  void cancel() override { call_->cancel(); }

 private:
  std::unique_ptr<H2Call> call_;
  const UtteranceRequests* requests_;  ///< null for Subscribe
};

class H2Client final : public LoadClient {
 public:
  H2Client(boost::asio::io_context& io, const std::string& address, const client::ClientOptions& options,
           int connections) {
    std::vector<std::pair<std::string, std::string>> headers;
    if (!options.api_key.empty()) {
      headers.emplace_back(std::string(client::kAuthorizationMetadataKey), "Bearer " + options.api_key);
    }
    for (int c = 0; c < connections; ++c) {
      try {
        connections_.push_back(std::make_unique<H2GrpcConnection>(io, address, headers, options.connect_timeout));
      } catch (const std::runtime_error& error) {
        throw client::CallError("connecting to lipsyncd at " + address, grpc::StatusCode::UNAVAILABLE, error.what());
      }
    }
  }
  std::size_t connections() const override { return connections_.size(); }

  std::unique_ptr<LoadCall> animate(std::size_t connection, const v1::AnimationSettings& settings,
                                    const UtteranceRequests& requests, client::MessageHandler on_message,
                                    client::DoneHandler on_done) override {
    v1::AnimateRequest first;
    *first.mutable_settings() = settings;
    return start(connection, kAnimatePath, settings.session(), first.SerializeAsString(), &requests,
                 std::move(on_message), std::move(on_done));
  }

  std::unique_ptr<LoadCall> subscribe(std::size_t connection, const std::string& session,
                                      client::MessageHandler on_message, client::DoneHandler on_done) override {
    v1::SubscribeRequest request;
    request.set_session(session);
    request.set_start(v1::SubscribeRequest::START_FROM_BEGINNING);
    auto call = start(connection, kSubscribePath, session, request.SerializeAsString(), nullptr, std::move(on_message),
                      std::move(on_done));
    call->end();  // a server-streaming call: its one request, then END_STREAM
    return call;
  }

  void close() override {
    for (auto& connection : connections_) connection->close();
  }

 private:
  std::unique_ptr<H2LoadCall> start(std::size_t connection, std::string_view path, const std::string& session,
                                    const std::string& first, const UtteranceRequests* requests,
                                    client::MessageHandler on_message, client::DoneHandler on_done) {
    std::vector<std::pair<std::string, std::string>> metadata;
    if (!session.empty()) metadata.emplace_back(std::string(client::kSessionMetadataKey), session);
    // One message object for every stream: the handlers run one at a time on the io thread,
    // and parsing into it again reuses its allocations.
    auto parse = [this, handler = std::move(on_message)](std::span<const std::uint8_t> bytes) {
      if (!parsed_.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) return false;
      handler(parsed_);
      return true;
    };
    auto done = [handler = std::move(on_done)](const H2CallStatus& status) {
      handler(grpc::Status(static_cast<grpc::StatusCode>(status.code), status.message));
    };
    return std::make_unique<H2LoadCall>(
        connections_[connection]->start(path, metadata, grpc_frame(first), std::move(parse), std::move(done)),
        requests);
  }

  std::vector<std::unique_ptr<H2GrpcConnection>> connections_;
  v1::TrackMessage parsed_;
};

}  // namespace

UtteranceRequests::UtteranceRequests(std::vector<client::v1::Phoneme> phonemes_in) : phonemes(std::move(phonemes_in)) {
  framed.reserve(phonemes.size() + 1);
  v1::AnimateRequest request;
  for (const v1::Phoneme& phoneme : phonemes) {
    request.Clear();
    *request.mutable_phonemes()->add_phonemes() = phoneme;
    framed.push_back(grpc_frame(request.SerializeAsString()));
  }
  request.Clear();
  request.mutable_end();
  framed.push_back(grpc_frame(request.SerializeAsString()));
}

std::unique_ptr<LoadClient> connect_load_client(LoadClientKind kind, boost::asio::io_context& io,
                                                const std::string& address, const client::ClientOptions& options,
                                                int connections) {
  if (kind == LoadClientKind::grpc) return std::make_unique<LibraryClient>(address, options, connections);
  return std::make_unique<H2Client>(io, address, options, connections);
}

std::string_view load_client_name(LoadClientKind kind) { return kind == LoadClientKind::h2 ? "h2" : "grpc"; }

}  // namespace lipsync::cli
