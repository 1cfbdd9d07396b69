// lipsyncd's admission limits over the network: --max-sessions (live and
// retained sessions count; an expired one frees its place) and
// --max-message-bytes (gRPC refuses the oversized request; every other call,
// on the same connection too, goes on). The other limits are in server_test.cpp.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <csignal>
#include <string>
#include <vector>

#include "../support/server_harness.hpp"

namespace lipsync::server {
namespace {

using namespace harness;
using ::testing::HasSubstr;

using LimitsTest = LiveServerTest;

constexpr std::int64_t kHourMs = 3'600'000;

/// A Render request of `phonemes` synthetic phonemes (about 15 bytes each on the wire).
v1::RenderRequest render_request(std::size_t phonemes) {
  v1::RenderRequest request;
  for (const auto& interval : utterance(phonemes, 5)) *request.add_phonemes() = to_proto(interval);
  return request;
}

grpc::Status render(v1::LipSync::Stub& stub, const v1::RenderRequest& request, v1::RenderResponse& response) {
  grpc::ClientContext context;
  set_deadline(context);
  return stub.Render(&context, request, &response);
}

/// Sends a short utterance on `producer`, ends it and returns what it received.
Received finish_utterance(Producer& producer, std::uint64_t seed = 2) {
  for (const auto& request : chunked(utterance(12, seed), 4)) producer.write(request);
  producer.write(end_request());
  return producer.finish();
}

// --- --max-sessions ----------------------------------------------------------------

TEST_F(LimitsTest, OneSessionMoreThanMaxSessionsIsRefusedNamingTheFlag) {
  ServerConfig config;
  config.max_sessions = 2;
  config.session_retention_ms = kHourMs;
  start(config);
  Producer first(*stub_, session_settings("first"));
  Producer second(*stub_, session_settings("second"));

  const Received third = animate(*stub_, whole(session_settings("third"), utterance(5), 5));
  EXPECT_EQ(third.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << third.status.error_message();
  EXPECT_THAT(third.status.error_message(), HasSubstr("--max-sessions=2"));
  EXPECT_FALSE(third.header.has_value());

  // A private stream holds no session, so the limit does not apply to it.
  const Received unnamed = animate(*stub_, whole({}, utterance(5), 5));
  EXPECT_TRUE(unnamed.status.ok()) << unnamed.status.error_message();

  EXPECT_TRUE(finish_utterance(first).status.ok());
  EXPECT_TRUE(finish_utterance(second).status.ok());
}

TEST_F(LimitsTest, AnEndedSessionCountsAgainstMaxSessionsWhileItIsRetained) {
  ServerConfig config;
  config.max_sessions = 1;
  config.session_retention_ms = kHourMs;
  start(config);
  Producer ended(*stub_, session_settings("ended"));
  const Received produced = finish_utterance(ended);
  ASSERT_TRUE(produced.status.ok()) << produced.status.error_message();

  const Received refused = animate(*stub_, whole(session_settings("next"), utterance(5), 5));
  EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.status.error_message(), HasSubstr("--max-sessions=1"));

  // It is still held: a late subscriber gets its frames.
  const Received late = subscribe_all(*stub_, "ended");
  ASSERT_TRUE(late.status.ok()) << late.status.error_message();
  EXPECT_EQ(late.frames.t_us, produced.frames.t_us);
}

TEST_F(LimitsTest, OnceAnEndedSessionsRetentionHasPassedANewSessionIsAdmitted) {
  ServerConfig config;
  config.max_sessions = 1;
  config.session_retention_ms = 100;
  start(config);
  Producer ended(*stub_, session_settings("ended"));
  ASSERT_TRUE(finish_utterance(ended).status.ok());

  // Refused (RESOURCE_EXHAUSTED) while "ended" is retained, admitted after.
  Received admitted;
  EXPECT_TRUE(eventually([&] {
    admitted = animate(*stub_, whole(session_settings("next"), utterance(5), 5));
    EXPECT_TRUE(admitted.status.ok() || admitted.status.error_code() == grpc::StatusCode::RESOURCE_EXHAUSTED)
        << admitted.status.error_message();
    return admitted.status.ok();
  }));
  EXPECT_TRUE(admitted.header.has_value());
  EXPECT_EQ(subscribe_all(*stub_, "ended").status.error_code(), grpc::StatusCode::NOT_FOUND);
}

// --- --max-message-bytes --------------------------------------------------------------

TEST_F(LimitsTest, ARequestOverMaxMessageBytesIsRefusedWhileOtherCallsGoOn) {
  ServerConfig config;
  config.max_message_bytes = 4096;
  start(config);
  // A stream that is running when the oversized requests arrive, on the same connection.
  Producer running(*stub_, session_settings("running"));
  Subscriber follower(*stub_, "running", v1::SubscribeRequest::START_FROM_BEGINNING);
  ASSERT_TRUE(follower.attached());

  const v1::RenderRequest big = render_request(1000);
  ASSERT_GT(big.ByteSizeLong(), 4096u);
  v1::RenderResponse response;
  const grpc::Status big_render = render(*stub_, big, response);
  EXPECT_EQ(big_render.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << big_render.error_message();
  EXPECT_THAT(big_render.error_message(), HasSubstr("4096"));

  const auto intervals = utterance(1000, 3);
  const Received big_chunk = animate(*stub_, whole({}, intervals, intervals.size()));
  EXPECT_EQ(big_chunk.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << big_chunk.status.error_message();

  // The same utterance in chunks under the limit is served, and so is the running stream.
  const Received small_chunks = animate(*stub_, whole({}, intervals, 50));
  ASSERT_TRUE(small_chunks.status.ok()) << small_chunks.status.error_message();
  EXPECT_GT(small_chunks.frames.t_us.size(), 0u);

  const Received produced = finish_utterance(running);
  ASSERT_TRUE(produced.status.ok()) << produced.status.error_message();
  const Received followed = follower.finish();
  ASSERT_TRUE(followed.status.ok()) << followed.status.error_message();
  EXPECT_EQ(followed.frames.t_us, produced.frames.t_us);
  EXPECT_EQ(followed.frames.values, produced.frames.values);

  const grpc::Status small_render = render(*stub_, render_request(100), response);
  EXPECT_TRUE(small_render.ok()) << small_render.error_message();
}

// --- the flags of the binary --------------------------------------------------------------

TEST(LipsyncdLimitFlags, MaxSessionsAndMaxMessageBytesFlagsSetTheLimits) {
  Child child = spawn({"--listen", "127.0.0.1:0", "--max-sessions", "1", "--max-message-bytes", "2048",
                       "--session-retention-ms", "3600000", "--log-level", "off"});
  const std::string address = listening_address(child);
  auto stub = v1::LipSync::NewStub(connect(address));
  {
    Producer live(*stub, session_settings("live"));
    const Received second = animate(*stub, whole(session_settings("second"), utterance(5), 5));
    EXPECT_EQ(second.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    EXPECT_THAT(second.status.error_message(), HasSubstr("--max-sessions=1"));

    v1::RenderResponse response;
    const v1::RenderRequest big = render_request(400);
    ASSERT_GT(big.ByteSizeLong(), 2048u);
    EXPECT_EQ(render(*stub, big, response).error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
    const grpc::Status small = render(*stub, render_request(20), response);
    EXPECT_TRUE(small.ok()) << small.error_message();
    EXPECT_TRUE(finish_utterance(live).status.ok());
  }
  stub.reset();  // the client goes away first: the drain then has nothing to wait for
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  EXPECT_EQ(child.wait(), 0);
}

}  // namespace
}  // namespace lipsync::server
