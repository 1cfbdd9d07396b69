// Session routing (server/src/sessions/session_routing.hpp): the x-lipsync-session metadata must equal the
// body's session, a Subscribe at a replica without its session gets a NOT_FOUND naming the replica,
// and the C++ client library sends the metadata on its own (seen by a recording fake server).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <mutex>

// RecordingService below hides the generated base's sync-API overloads on purpose (as
// server/src/rpc/service.hpp does): the warning points into the generated header, so it is
// silenced for the whole file.
#pragma GCC diagnostic ignored "-Woverloaded-virtual"
#include "../support/server_harness.hpp"
#include "lipsync/client/animation_client.hpp"

namespace lipsync::server {
namespace {

using harness::LiveServerTest;
using ::testing::AllOf;
using ::testing::HasSubstr;

class SessionRoutingTest : public LiveServerTest {
 protected:
  void SetUp() override {
    ServerConfig config;
    config.replica_name = "replica-b";
    start(config);
  }
};

TEST_F(SessionRoutingTest, AnAnimateWhoseMetadataNamesAnotherSessionIsRefusedNamingBoth) {
  grpc::ClientContext context;
  harness::set_deadline(context);
  context.AddMetadata("x-lipsync-session", "alice");
  auto stream = stub_->Animate(&context);
  stream->Write(harness::settings_request(harness::session_settings("bob")));
  stream->WritesDone();
  v1::TrackMessage message;
  while (stream->Read(&message)) {
  }
  const grpc::Status status = stream->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), AllOf(HasSubstr("x-lipsync-session 'alice'"), HasSubstr("session 'bob'")));
  EXPECT_EQ(server_->session_count(), 0u);
}

TEST_F(SessionRoutingTest, ASubscribeWhoseMetadataNamesAnotherSessionIsRefusedNamingBoth) {
  grpc::ClientContext context;
  harness::set_deadline(context);
  context.AddMetadata("x-lipsync-session", "alice");
  v1::SubscribeRequest request;
  request.set_session("bob");
  auto reader = stub_->Subscribe(&context, request);
  v1::TrackMessage message;
  while (reader->Read(&message)) {
  }
  const grpc::Status status = reader->Finish();
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), AllOf(HasSubstr("'alice'"), HasSubstr("'bob'")));
}

TEST_F(SessionRoutingTest, MatchingMetadataStreamsAndSubscribesAsWithout) {
  client::AnimationClient client(server_->address());
  v1::AnimationSettings settings = harness::session_settings("carol");
  std::vector<std::vector<v1::Phoneme>> chunks(1);
  for (const auto& interval : harness::utterance(12, 3)) chunks[0].push_back(harness::to_proto(interval));
  const client::ReceivedTrack produced = client.animate(settings, chunks);
  const client::ReceivedTrack followed = client.subscribe("carol", v1::SubscribeRequest::START_FROM_BEGINNING);
  EXPECT_GT(produced.track.frame_count(), 0u);
  EXPECT_EQ(followed.track.t_us, produced.track.t_us);
}

TEST_F(SessionRoutingTest, ASubscribeAtAReplicaWithoutTheSessionNamesTheReplicaAndHowSessionsAreRouted) {
  const harness::Received received = harness::subscribe_all(*stub_, "elsewhere");
  EXPECT_EQ(received.status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(received.status.error_message(),
              AllOf(HasSubstr("no session named 'elsewhere' at replica replica-b"), HasSubstr("not held here"),
                    HasSubstr("x-lipsync-session"), HasSubstr("consistent hash")));
}

TEST(SessionRoutingDefaults, AReplicaWithoutANameIsNamedByItsHostAndBoundAddress) {
  ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.log_level = "warn";
  Server server(config);
  auto stub = v1::LipSync::NewStub(harness::connect(server.address()));
  const harness::Received received = harness::subscribe_all(*stub, "nobody");
  EXPECT_THAT(received.status.error_message(), HasSubstr("(" + server.address() + ")"));
  server.shutdown(std::chrono::milliseconds(0));
}

// A LipSync service that only records the metadata of the calls it gets, then refuses them.
class RecordingService final : public v1::LipSync::CallbackService {
 public:
  grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage>* Animate(
      grpc::CallbackServerContext* context) override {
    record(*context);
    class Refuse : public grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage> {
     public:
      Refuse() { Finish({grpc::StatusCode::UNIMPLEMENTED, "recording only"}); }
      void OnDone() override { delete this; }
    };
    return new Refuse;
  }
  grpc::ServerWriteReactor<v1::TrackMessage>* Subscribe(grpc::CallbackServerContext* context,
                                                        const v1::SubscribeRequest*) override {
    record(*context);
    class Refuse : public grpc::ServerWriteReactor<v1::TrackMessage> {
     public:
      Refuse() { Finish({grpc::StatusCode::UNIMPLEMENTED, "recording only"}); }
      void OnDone() override { delete this; }
    };
    return new Refuse;
  }
  std::vector<std::string> sessions() {
    std::lock_guard lock(mutex_);
    return sessions_;
  }

 private:
  void record(const grpc::CallbackServerContext& context) {
    std::lock_guard lock(mutex_);
    const auto found = context.client_metadata().find("x-lipsync-session");
    sessions_.push_back(
        found == context.client_metadata().end() ? "(none)" : std::string(found->second.data(), found->second.size()));
  }
  std::mutex mutex_;
  std::vector<std::string> sessions_;
};

TEST(ClientLibrary, SendsTheSessionAsMetadataOnAnimateAndSubscribe) {
  RecordingService service;
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service);
  auto server = builder.BuildAndStart();
  ASSERT_NE(port, 0);
  client::AnimationClient client("127.0.0.1:" + std::to_string(port));
  const std::vector<std::vector<v1::Phoneme>> none;
  EXPECT_THROW(client.animate(harness::session_settings("dave"), none), client::CallError);
  EXPECT_THROW(client.animate(v1::AnimationSettings{}, none), client::CallError);  // private: no metadata
  EXPECT_THROW(client.subscribe("erin", v1::SubscribeRequest::START_FROM_NOW), client::CallError);
  EXPECT_EQ(service.sessions(), (std::vector<std::string>{"dave", "(none)", "erin"}));
  server->Shutdown();
}

}  // namespace
}  // namespace lipsync::server
