// lipsyncd over the network: Animate equals Render equals render_track, fan-out
// to many subscribers, a slow subscriber cut off without hurting the others,
// replay, cancellation, validation errors, limits, models, health, and the
// binary's flags, exit codes and SIGTERM drain.
#include "lipsync/server/server.hpp"

#include <gmock/gmock.h>
#include <grpcpp/create_channel_posix.h>
#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <future>
#include <string>
#include <thread>

#include "../support/server_harness.hpp"
#include "lipsync/error.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/release_delay.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/server/config.hpp"
#include "lipsync/synthetic.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace lipsync::server {
namespace {

using namespace harness;
using ::testing::HasSubstr;
using namespace std::chrono_literals;
using ServerTest = LiveServerTest;

// --- the expected frames, from the core engine directly --------------------

void expect_same(const Frames& actual, const Frames& expected) {
  ASSERT_EQ(actual.t_us.size(), expected.t_us.size());
  EXPECT_EQ(actual.t_us, expected.t_us);
  EXPECT_EQ(actual.kinds, expected.kinds);
  EXPECT_EQ(actual.values, expected.values);
  EXPECT_EQ(actual.arkit, expected.arkit);
}

Frames reference_frames(const std::vector<LabeledInterval>& intervals, int fps = 30) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  const Track track = render_track(model, build_segments({"test", "", intervals}, model, arpabet), {.fps = fps});
  Frames frames;
  frames.t_us = track.t_us;
  frames.values = track.values;
  std::array<float, 52> arkit{};
  for (std::size_t i = 0; i < track.frame_count(); ++i) {
    frames.kinds.push_back(static_cast<int>(track.kinds[i]) + 1);
    model.retarget_to_arkit(track.frame_values(i), arkit);
    frames.arkit.insert(frames.arkit.end(), arkit.begin(), arkit.end());
  }
  return frames;
}

v1::Phoneme phoneme(const std::string& label, std::int64_t start_us, std::int64_t end_us) {
  return to_proto({label, start_us, end_us, 0});
}

// --- Animate, Render, render_track ---------------------------------------------

TEST_F(ServerTest, AnimateEqualsRenderEqualsRenderTrackForEveryChunking) {
  const auto intervals = utterance(300, 7);
  const Frames expected = reference_frames(intervals);

  v1::RenderRequest render;
  for (const auto& interval : intervals) *render.add_phonemes() = to_proto(interval);
  v1::RenderResponse response;
  grpc::ClientContext context;
  set_deadline(context);
  ASSERT_TRUE(stub_->Render(&context, render, &response).ok());
  Frames rendered;
  rendered.append(response.frames());
  expect_same(rendered, expected);
  EXPECT_EQ(response.summary().frames(), expected.t_us.size());
  EXPECT_EQ(response.header().channels_size(), 16);
  EXPECT_EQ(response.header().arkit_names_size(), 52);

  for (std::size_t chunk : {1u, 3u, 17u, 300u}) {
    SCOPED_TRACE("chunk " + std::to_string(chunk));
    const Received received = animate(*stub_, whole({}, intervals, chunk));
    ASSERT_TRUE(received.status.ok()) << received.status.error_message();
    ASSERT_TRUE(received.header.has_value());
    EXPECT_EQ(received.header->fps(), 30u);
    EXPECT_EQ(received.header->lookahead(), 7u);
    expect_same(received.frames, expected);
    ASSERT_TRUE(received.summary.has_value());
    EXPECT_EQ(received.summary->frames(), expected.t_us.size());
    EXPECT_EQ(received.summary->phonemes(), 300u);
    EXPECT_EQ(received.summary->duration_us(), intervals.back().end_us);
    // Frames come in batches, not one message per frame.
    EXPECT_LT(received.batches, expected.t_us.size() / 2);
  }
}

TEST_F(ServerTest, OutputSelectionAndFpsShapeTheFrames) {
  const auto intervals = utterance(60, 3);
  v1::AnimationSettings settings;
  settings.set_fps(60);
  settings.mutable_outputs()->set_arkit(true);
  const Received received = animate(*stub_, whole(settings, intervals, 5));
  ASSERT_TRUE(received.status.ok()) << received.status.error_message();
  EXPECT_EQ(received.header->channels_size(), 0);
  EXPECT_EQ(received.header->arkit_names_size(), 52);
  const Frames expected = reference_frames(intervals, 60);
  EXPECT_EQ(received.frames.t_us, expected.t_us);
  EXPECT_TRUE(received.frames.values.empty());
  EXPECT_EQ(received.frames.arkit, expected.arkit);
}

// --- sessions -------------------------------------------------------------------

TEST_F(ServerTest, TwentySubscribersReceiveIdenticalFramesEqualToRender) {
  const auto intervals = utterance(200, 11);
  const Frames expected = reference_frames(intervals);
  Producer producer(*stub_, session_settings("fan"));
  std::vector<std::unique_ptr<Subscriber>> subscribers;
  for (int i = 0; i < 20; ++i) {
    subscribers.push_back(std::make_unique<Subscriber>(*stub_, "fan", v1::SubscribeRequest::START_FROM_NOW));
    ASSERT_TRUE(subscribers.back()->attached());
  }
  std::vector<std::future<Received>> results;
  for (auto& subscriber : subscribers) {
    results.push_back(std::async(std::launch::async, [&s = *subscriber] { return s.finish(); }));
  }
  for (auto& request : chunked(intervals, 9)) producer.write(request);
  producer.write(end_request());
  const Received produced = producer.finish();
  ASSERT_TRUE(produced.status.ok()) << produced.status.error_message();
  expect_same(produced.frames, expected);
  for (auto& result : results) {
    const Received received = result.get();
    ASSERT_TRUE(received.status.ok()) << received.status.error_message();
    EXPECT_EQ(received.header->session(), "fan");
    EXPECT_EQ(received.header->media_clock().clock(), "unix");
    EXPECT_EQ(received.header->media_clock().utterance_zero_us(), 1'700'000'000'000'000);
    expect_same(received.frames, expected);
    ASSERT_TRUE(received.summary.has_value());
    EXPECT_EQ(received.summary->frames(), expected.t_us.size());
  }
}

TEST_F(ServerTest, SubscribersGetTheProducersMessagesByteForByteWithTheReleaseDelayAndLags) {
  // The session serialises each message once and every subscriber writes those
  // bytes (a raw method): what a subscriber reads must be exactly what the
  // producer read, message for message.
  const auto intervals = utterance(60, 5);
  std::vector<std::string> produced;
  {
    grpc::ClientContext context;
    set_deadline(context);
    auto stream = stub_->Animate(&context);
    std::thread reader([&] {
      v1::TrackMessage message;
      while (stream->Read(&message)) produced.push_back(message.SerializeAsString());
    });
    for (const auto& request : whole(session_settings("bytes"), intervals, 1)) stream->Write(request);
    stream->WritesDone();
    reader.join();
    ASSERT_TRUE(stream->Finish().ok());
  }
  ASSERT_GT(produced.size(), 3u);
  for (int s = 0; s < 3; ++s) {
    const SubscribedBytes followed = subscribe_bytes(*stub_, "bytes");
    ASSERT_TRUE(followed.status.ok()) << followed.status.error_message();
    EXPECT_EQ(followed.messages, produced) << "subscriber " << s;
  }
  v1::TrackMessage header;
  ASSERT_TRUE(header.ParseFromString(produced.front()));
  EXPECT_EQ(header.header().release_delay_us(), read_speech_release_delay_us(7));
  // Each batch says how far it is behind the newest phoneme; the last one was released by `end`.
  v1::TrackMessage last;
  ASSERT_TRUE(last.ParseFromString(produced[produced.size() - 2]));
  ASSERT_TRUE(last.has_frames());
  EXPECT_EQ(last.frames().release_lag_us(), intervals.back().end_us - last.frames().t_us(0));
  for (std::size_t i = 1; i + 1 < produced.size(); ++i) {
    v1::TrackMessage batch;
    ASSERT_TRUE(batch.ParseFromString(produced[i]));
    EXPECT_GE(batch.frames().release_lag_us(), 0) << "batch " << i;
  }
}

TEST_F(ServerTest, ARenderStatesTheReleaseDelayOfItsLookaheadButNoLag) {
  v1::RenderRequest render;
  for (const auto& interval : utterance(10, 2)) *render.add_phonemes() = to_proto(interval);
  v1::RenderResponse response;
  grpc::ClientContext context;
  set_deadline(context);
  ASSERT_TRUE(stub_->Render(&context, render, &response).ok());
  EXPECT_EQ(response.header().release_delay_us(), read_speech_release_delay_us(7));
  EXPECT_EQ(response.frames().release_lag_us(), 0);
}

TEST_F(ServerTest, ASlowSubscriberIsCutOffWhileTheOthersFinish) {
  ServerConfig config;
  config.subscriber_queue_frames = 4000;
  config.replay_frames = 64;
  config.stalled_subscriber_ms = 600'000;  // it reads on at the end: RESOURCE_EXHAUSTED, not a cancel
  start(config);
  const auto intervals = utterance(1500, 5);
  v1::AnimationSettings settings = session_settings("slow");
  settings.set_fps(120);
  const Frames expected = reference_frames(intervals, 120);

  Producer producer(*stub_, settings);
  auto slow_channel = connect(server_->address(), false);
  auto slow_stub = v1::LipSync::NewStub(slow_channel);
  Subscriber slow(*slow_stub, "slow", v1::SubscribeRequest::START_FROM_NOW);
  ASSERT_TRUE(slow.attached());
  std::vector<std::unique_ptr<Subscriber>> fast;
  std::vector<std::future<Received>> results;
  for (int i = 0; i < 3; ++i) {
    fast.push_back(std::make_unique<Subscriber>(*stub_, "slow", v1::SubscribeRequest::START_FROM_NOW));
    ASSERT_TRUE(fast.back()->attached());
    results.push_back(std::async(std::launch::async, [&s = *fast.back()] { return s.finish(); }));
  }
  auto produced = std::async(std::launch::async, [&] {
    // Paced like a live producer: each chunk's first frames come back before the next is sent.
    for (auto& request : chunked(intervals, 20)) {
      producer.write(request);
      producer.read_message();
    }
    producer.write(end_request());
    return producer.finish();
  });
  const Received producer_result = produced.get();
  ASSERT_TRUE(producer_result.status.ok()) << producer_result.status.error_message();
  for (auto& result : results) {
    const Received received = result.get();
    ASSERT_TRUE(received.status.ok()) << received.status.error_message();
    ASSERT_EQ(received.frames.t_us.size(), expected.t_us.size());
  }
  const Received cut = slow.finish();
  EXPECT_EQ(cut.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(cut.status.error_message(), HasSubstr("--subscriber-queue-frames=4000"));
  EXPECT_LT(cut.frames.t_us.size(), expected.t_us.size());
  EXPECT_FALSE(cut.summary.has_value());
}

TEST_F(ServerTest, ASubscriberThatStopsReadingIsCancelledAndItsStreamFreed) {
  ServerConfig config;
  config.subscriber_queue_frames = 1000;
  config.replay_frames = 64;
  config.stalled_subscriber_ms = 200;
  start(config);
  const auto intervals = utterance(600, 6);
  v1::AnimationSettings settings = session_settings("stalled");
  settings.set_fps(120);

  Producer producer(*stub_, settings);
  // Its own connection without BDP probing, so flow control stops the server's
  // writes to it after about 64 kB; it reads the header and then nothing.
  auto dead_channel = connect(server_->address(), false);
  auto dead_stub = v1::LipSync::NewStub(dead_channel);
  Subscriber dead(*dead_stub, "stalled", v1::SubscribeRequest::START_FROM_NOW);
  ASSERT_TRUE(dead.attached());
  ASSERT_EQ(server_->active_streams(), 2u);
  // Small messages (one phoneme, about 14 frames): the queue fills behind a
  // write that flow control holds back.
  for (auto& request : chunked(intervals, 1)) producer.write(request);
  producer.write(end_request());
  const Received produced = producer.finish();
  ASSERT_TRUE(produced.status.ok()) << produced.status.error_message();
  // Cut off with a write stuck in flight, it is cancelled after the grace period
  // although its client never reads again: its stream slot is free.
  EXPECT_TRUE(eventually([&] { return server_->active_streams() == 0; }))
      << server_->active_streams() << " streams still open";
  const Received cut = dead.finish();
  EXPECT_FALSE(cut.status.ok());
  EXPECT_LT(cut.frames.t_us.size(), produced.frames.t_us.size());
}

TEST_F(ServerTest, AProducerThatDoesNotReadIsHeldBackAndLosesNothing) {
  // 20,000 phonemes (about 70,000 frames) sent at once by a producer that reads
  // no frame: once thousands of frames wait for it, the server stops reading its
  // phonemes (flow control then holds the client back) instead of rendering and
  // queueing the whole track. A subscriber of its session shows how far the
  // server got. Once the producer reads, everything arrives, to both.
  ServerConfig config;
  config.subscriber_queue_frames = 200'000;  // the follower must not be cut off while the producer catches up
  start(config);
  const auto intervals = utterance(20'000, 12);
  const Frames expected = reference_frames(intervals);
  // Without BDP probing the producer's receive window stays at 64 kB.
  auto channel = connect(server_->address(), false);
  auto stub = v1::LipSync::NewStub(channel);
  grpc::ClientContext context;
  set_deadline(context);
  auto stream = stub->Animate(&context);
  ASSERT_TRUE(stream->Write(settings_request(session_settings("held"))));
  v1::TrackMessage header;
  ASSERT_TRUE(stream->Read(&header));
  grpc::ClientContext follow_context;
  set_deadline(follow_context);
  v1::SubscribeRequest follow;
  follow.set_session("held");
  auto follower = stub_->Subscribe(&follow_context, follow);
  Received followed;
  std::atomic<std::size_t> followed_frames{0};
  std::thread follower_thread([&] {
    v1::TrackMessage message;
    while (follower->Read(&message)) {
      take(followed, message);
      followed_frames = followed.frames.t_us.size();
    }
  });
  std::thread writer([&] {
    for (auto& request : chunked(intervals, 20)) {
      if (!stream->Write(request)) return;
    }
    if (stream->Write(end_request())) stream->WritesDone();
  });
  // Until the server stops making progress on this producer's phonemes.
  std::size_t seen = 0;
  auto progress = std::chrono::steady_clock::now();
  while (followed_frames < expected.t_us.size() && std::chrono::steady_clock::now() - progress < 500ms) {
    std::this_thread::sleep_for(10ms);
    if (followed_frames != seen) {
      seen = followed_frames;
      progress = std::chrono::steady_clock::now();
    }
  }
  EXPECT_LT(followed_frames.load(), expected.t_us.size() / 2)
      << "the server rendered the track although its producer read no frame";
  Received received;
  take(received, header);
  read_all(*stream, received);
  writer.join();
  received.status = stream->Finish();
  ASSERT_TRUE(received.status.ok()) << received.status.error_message();
  expect_same(received.frames, expected);
  follower_thread.join();
  followed.status = follower->Finish();
  ASSERT_TRUE(followed.status.ok()) << followed.status.error_message();
  expect_same(followed.frames, expected);
}

TEST_F(ServerTest, FromNowSkipsWhatFromBeginningReplays) {
  const auto intervals = utterance(120, 9);
  const Frames expected = reference_frames(intervals);
  const auto requests = chunked(intervals, 40);
  Producer producer(*stub_, session_settings("replay"));
  producer.write(requests[0]);
  producer.read_frames(1);  // the session has published these frames
  Subscriber from_now(*stub_, "replay", v1::SubscribeRequest::START_FROM_NOW);
  Subscriber from_beginning(*stub_, "replay", v1::SubscribeRequest::START_FROM_BEGINNING);
  ASSERT_TRUE(from_now.attached());
  ASSERT_TRUE(from_beginning.attached());
  for (std::size_t i = 1; i < requests.size(); ++i) producer.write(requests[i]);
  producer.write(end_request());
  ASSERT_TRUE(producer.finish().status.ok());

  const Received all = from_beginning.finish();
  ASSERT_TRUE(all.status.ok());
  expect_same(all.frames, expected);
  const Received later = from_now.finish();
  ASSERT_TRUE(later.status.ok());
  ASSERT_GT(later.frames.first_frame, 0u);
  const auto first = static_cast<std::ptrdiff_t>(later.frames.first_frame);
  EXPECT_EQ(later.frames.t_us, std::vector<std::int64_t>(expected.t_us.begin() + first, expected.t_us.end()));

  // A late joiner of the finished session replays it; FROM_NOW gets header and summary only.
  const Received late = subscribe_all(*stub_, "replay");
  ASSERT_TRUE(late.status.ok());
  expect_same(late.frames, expected);
  const Received late_now = subscribe_all(*stub_, "replay", v1::SubscribeRequest::START_FROM_NOW);
  ASSERT_TRUE(late_now.status.ok());
  EXPECT_TRUE(late_now.frames.t_us.empty());
  EXPECT_TRUE(late_now.summary.has_value());
}

TEST_F(ServerTest, ReplayStartsAtTheOldestHeldFrameWhenTheBeginningWasDropped) {
  ServerConfig config;
  config.replay_frames = 100;
  start(config);
  const auto intervals = utterance(200, 2);
  const Frames expected = reference_frames(intervals);
  ASSERT_TRUE(animate(*stub_, whole(session_settings("short"), intervals, 10)).status.ok());
  const Received late = subscribe_all(*stub_, "short");
  ASSERT_TRUE(late.status.ok());
  ASSERT_TRUE(late.header.has_value());
  EXPECT_GT(late.frames.first_frame, 0u);
  EXPECT_LE(late.frames.t_us.size(), 100u + 512u);
  EXPECT_EQ(late.frames.t_us.back(), expected.t_us.back());
}

TEST_F(ServerTest, UnknownSessionIsNotFoundAndExpiredSessionsAreDropped) {
  EXPECT_EQ(subscribe_all(*stub_, "nobody").status.error_code(), grpc::StatusCode::NOT_FOUND);
  ServerConfig config;
  config.session_retention_ms = 0;
  start(config);
  ASSERT_TRUE(animate(*stub_, whole(session_settings("brief"), utterance(10), 10)).status.ok());
  EXPECT_EQ(subscribe_all(*stub_, "brief").status.error_code(), grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(server_->session_count(), 0u);
}

// The registry forgets an ended session once its retention has passed, by the queue of ended
// sessions (session.hpp); a new producer that took the name meanwhile is not forgotten with it.
TEST_F(ServerTest, ANameReusedAfterItsSessionEndedOutlivesTheOldSessionsRetention) {
  ServerConfig config;
  config.session_retention_ms = 200;
  start(config);
  ASSERT_TRUE(animate(*stub_, whole(session_settings("reused"), utterance(5), 5)).status.ok());
  Producer second(*stub_, session_settings("reused"));  // replaces the ended one
  second.write(chunked(utterance(20, 3), 10)[0]);
  std::this_thread::sleep_for(std::chrono::milliseconds(400));  // the first one's retention is over
  Subscriber follower(*stub_, "reused", v1::SubscribeRequest::START_FROM_BEGINNING);
  ASSERT_TRUE(follower.attached());
  EXPECT_EQ(server_->session_count(), 1u);
  second.write(end_request());
  EXPECT_TRUE(second.finish().status.ok());
  EXPECT_TRUE(follower.finish().status.ok());
}

TEST_F(ServerTest, ASecondLiveProducerForTheSameSessionIsRefused) {
  Producer first(*stub_, session_settings("taken"));
  const Received second = animate(*stub_, whole(session_settings("taken"), utterance(5), 5));
  EXPECT_EQ(second.status.error_code(), grpc::StatusCode::ALREADY_EXISTS);
  first.write(end_request());
  ASSERT_TRUE(first.finish().status.ok());
  // Ended: the name may be reused.
  EXPECT_TRUE(animate(*stub_, whole(session_settings("taken"), utterance(5), 5)).status.ok());
}

TEST_F(ServerTest, CancellingTheProducerAbortsSubscribersAndFreesTheStreams) {
  const auto requests = chunked(utterance(100, 4), 20);
  auto producer = std::make_unique<Producer>(*stub_, session_settings("cancel"));
  producer->write(requests[0]);
  Subscriber subscriber(*stub_, "cancel", v1::SubscribeRequest::START_FROM_BEGINNING);
  ASSERT_TRUE(subscriber.attached());
  EXPECT_EQ(server_->active_streams(), 2u);
  producer->cancel();
  const Received aborted = subscriber.finish();
  EXPECT_EQ(aborted.status.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_THAT(aborted.status.error_message(), HasSubstr("producer"));
  producer->finish();
  producer.reset();
  EXPECT_TRUE(eventually([&] { return server_->active_streams() == 0; }));
  EXPECT_EQ(subscribe_all(*stub_, "cancel").status.error_code(), grpc::StatusCode::ABORTED);
}

// --- validation -------------------------------------------------------------------

struct BadStream {
  std::string name;
  std::vector<v1::AnimateRequest> requests;
  std::string message;
};

v1::AnimationSettings with(void (*change)(v1::AnimationSettings&)) {
  v1::AnimationSettings settings;
  change(settings);
  return settings;
}

TEST_F(ServerTest, BadInputEndsTheStreamWithInvalidArgumentNamingThePhoneme) {
  const auto aa = phoneme("AA", 0, 100'000);
  const std::vector<BadStream> cases = {
      {"unknown label",
       {settings_request(), chunk_request({aa, phoneme("XQ", 100'000, 200'000)}), end_request()},
       "phoneme stream:2: phoneme 'XQ'"},
      {"reversed times",
       {settings_request(), chunk_request({aa, phoneme("B", 300'000, 200'000)}), end_request()},
       "phoneme stream:2:"},
      {"overlap",
       {settings_request(), chunk_request({aa, phoneme("B", 50'000, 200'000)}), end_request()},
       "phoneme stream:2:"},
      {"backwards across chunks",
       {settings_request(), chunk_request({aa, phoneme("B", 100'000, 200'000)}),
        chunk_request({phoneme("K", 150'000, 250'000)}), end_request()},
       "phoneme stream:3:"},
      {"missing settings", {chunk_request({aa}), end_request()}, "first message must be settings"},
      {"second settings",
       {settings_request(), chunk_request({aa}), settings_request(), end_request()},
       "settings sent twice"},
      {"phoneme after end",
       {settings_request(), chunk_request({aa}), end_request(), chunk_request({phoneme("B", 100'000, 200'000)})},
       "phoneme stream:2: phoneme 'B': received after `end`"},
      {"fps", {settings_request(with([](auto& s) { s.set_fps(241); }))}, "settings.fps"},
      {"lookahead", {settings_request(with([](auto& s) { s.set_lookahead(8); }))}, "settings.lookahead"},
      {"phone set", {settings_request(with([](auto& s) { s.set_phone_set("klingon"); }))}, "settings.phone_set"},
      {"model", {settings_request(with([](auto& s) { s.set_model("nope"); }))}, "settings.model"},
      {"closure fraction",
       {settings_request(with([](auto& s) { s.set_closure_fraction(1.5); }))},
       "settings.closure_fraction"},
  };
  for (const auto& bad : cases) {
    SCOPED_TRACE(bad.name);
    const Received received = animate(*stub_, bad.requests);
    EXPECT_EQ(received.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(received.status.error_message(), HasSubstr(bad.message));
  }
  EXPECT_TRUE(eventually([&] { return server_->active_streams() == 0; }));

  v1::RenderRequest render;
  *render.add_phonemes() = aa;
  *render.add_phonemes() = phoneme("XQ", 100'000, 200'000);
  v1::RenderResponse response;
  grpc::ClientContext context;
  set_deadline(context);
  const grpc::Status status = stub_->Render(&context, render, &response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("phoneme stream:2: phoneme 'XQ'"));
}

// --- limits ----------------------------------------------------------------------

TEST_F(ServerTest, LimitsEndCallsWithResourceExhaustedNamingTheLimit) {
  ServerConfig config;
  config.max_phonemes = 10;
  config.max_utterance_ms = 1000;
  config.max_streams = 2;
  config.max_subscribers_per_session = 1;
  start(config);
  const auto many = animate(*stub_, whole({}, utterance(11), 3));
  EXPECT_EQ(many.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(many.status.error_message(), HasSubstr("--max-phonemes=10"));

  const auto long_one = animate(*stub_, whole({}, {{"AA", 0, 2'000'000, 0}}, 1));
  EXPECT_EQ(long_one.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(long_one.status.error_message(), HasSubstr("--max-utterance-ms=1000"));
  // The client may see a status before the server has released the stream.
  ASSERT_TRUE(eventually([&] { return server_->active_streams() == 0; }));

  Producer producer(*stub_, session_settings("limited"));
  Subscriber subscriber(*stub_, "limited", v1::SubscribeRequest::START_FROM_NOW);
  ASSERT_TRUE(subscriber.attached());
  const auto third = animate(*stub_, whole({}, utterance(3), 3));
  EXPECT_EQ(third.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(third.status.error_message(), HasSubstr("--max-streams=2"));
  producer.write(end_request());
  ASSERT_TRUE(producer.finish().status.ok());
  ASSERT_TRUE(subscriber.finish().status.ok());
  EXPECT_TRUE(eventually([&] { return server_->active_streams() == 0; }));

  Producer again(*stub_, session_settings("limited2"));
  Subscriber one(*stub_, "limited2", v1::SubscribeRequest::START_FROM_NOW);
  ASSERT_TRUE(one.attached());
  EXPECT_TRUE(eventually([&] { return server_->active_streams() == 2; }));
  again.write(end_request());
  ASSERT_TRUE(again.finish().status.ok());
}

TEST_F(ServerTest, TooManySubscribersOfOneSession) {
  ServerConfig config;
  config.max_subscribers_per_session = 1;
  start(config);
  Producer producer(*stub_, session_settings("one"));
  Subscriber first(*stub_, "one", v1::SubscribeRequest::START_FROM_NOW);
  ASSERT_TRUE(first.attached());
  const Received second = subscribe_all(*stub_, "one");
  EXPECT_EQ(second.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(second.status.error_message(), HasSubstr("--max-subscribers-per-session=1"));
  producer.write(end_request());
  ASSERT_TRUE(producer.finish().status.ok());
  ASSERT_TRUE(first.finish().status.ok());
}

// --- models and health -------------------------------------------------------------

TEST_F(ServerTest, ListsAndDescribesModels) {
  ServerConfig config;
  config.models.push_back({"minimal", LIPSYNC_TEST_DATA_DIR "/models/valid_minimal.json"});
  start(config);
  v1::ListModelsResponse list;
  grpc::ClientContext list_context;
  set_deadline(list_context);
  ASSERT_TRUE(stub_->ListModels(&list_context, {}, &list).ok());
  ASSERT_EQ(list.models_size(), 2);
  const auto& builtin = list.models(0);
  EXPECT_EQ(builtin.name(), ArticulationModel::builtin().name());
  EXPECT_TRUE(builtin.is_default());
  EXPECT_EQ(builtin.channels_size(), 16);
  EXPECT_EQ(builtin.arkit_names_size(), 52);
  EXPECT_THAT(std::vector<std::string>(builtin.phone_sets().begin(), builtin.phone_sets().end()),
              ::testing::Contains("arpabet"));
  EXPECT_EQ(list.models(1).name(), "minimal");
  EXPECT_FALSE(list.models(1).is_default());

  v1::ModelInfo info;
  grpc::ClientContext get_context;
  set_deadline(get_context);
  ASSERT_TRUE(stub_->GetModel(&get_context, {}, &info).ok());
  EXPECT_EQ(info.name(), builtin.name());
  v1::GetModelRequest unknown;
  unknown.set_name("nope");
  grpc::ClientContext missing_context;
  set_deadline(missing_context);
  EXPECT_EQ(stub_->GetModel(&missing_context, unknown, &info).error_code(), grpc::StatusCode::NOT_FOUND);

  ServerConfig bad;
  bad.listen = "127.0.0.1:0";
  bad.models.push_back({"bad", LIPSYNC_TEST_DATA_DIR "/models/bad_alpha.json"});
  EXPECT_THROW(Server{bad}, InputError);
}

TEST_F(ServerTest, HealthCheckSaysServing) {
  grpc::GenericStub generic(channel_);
  grpc::ClientContext context;
  set_deadline(context);
  grpc::Slice empty("");  // HealthCheckRequest{service: ""} encodes to nothing
  grpc::ByteBuffer request(&empty, 1);
  grpc::ByteBuffer response;
  std::promise<grpc::Status> done;
  generic.UnaryCall(&context, "/grpc.health.v1.Health/Check", grpc::StubOptions(), &request, &response,
                    [&](grpc::Status status) { done.set_value(status); });
  const grpc::Status status = done.get_future().get();
  ASSERT_TRUE(status.ok()) << status.error_message();
  std::vector<grpc::Slice> slices;
  ASSERT_TRUE(response.Dump(&slices).ok());
  std::string bytes;
  for (const auto& slice : slices) bytes.append(reinterpret_cast<const char*>(slice.begin()), slice.size());
  EXPECT_EQ(bytes, std::string("\x08\x01", 2));  // status: SERVING
}

// --- configuration ------------------------------------------------------------------

TEST(ServerConfigTest, FlagsOverrideTheFileAndBadValuesNameTheFlag) {
  const std::string path = ::testing::TempDir() + "/lipsyncd_config.json";
  std::ofstream(path) << R"({"max-streams": 7, "listen": "0.0.0.0:6000", "replay-frames": 50})";
  const auto line = parse_command_line({"--config", path, "--max-streams=9"});
  EXPECT_EQ(line.config.max_streams, 9u);
  EXPECT_EQ(line.config.listen, "0.0.0.0:6000");
  EXPECT_EQ(line.config.replay_frames, 50u);
  EXPECT_TRUE(parse_command_line({"--help"}).help);
  try {
    parse_command_line({"--max-streams", "lots"});
    FAIL();
  } catch (const ConfigError& error) {
    EXPECT_THAT(error.what(), HasSubstr("--max-streams"));
  }
  EXPECT_THROW(parse_command_line({"--bogus", "1"}), ConfigError);
  EXPECT_THROW(parse_command_line({"--listen", "nowhere"}), ConfigError);
  EXPECT_THAT(help_text(), HasSubstr("--drain-deadline-ms MS"));
  EXPECT_THAT(help_text(), HasSubstr("(default: 5000)"));
}

// --- the binary ------------------------------------------------------------------------

TEST(LipsyncdBinary, BadFlagsExit2AndABadModelExits1) {
  EXPECT_EQ(spawn({"--max-streams", "-3"}).wait(), 2);
  EXPECT_EQ(spawn({"--no-such-flag"}).wait(), 2);
  EXPECT_EQ(spawn({"--listen", "127.0.0.1:0", "--model", "bad=" LIPSYNC_TEST_DATA_DIR "/models/bad_alpha.json"}).wait(),
            1);
  Child help = spawn({"--help"});
  EXPECT_THAT(help.line(), HasSubstr("lipsyncd"));
  EXPECT_EQ(help.wait(), 0);
}

TEST(LipsyncdBinary, SigtermLetsAnOpenStreamFinishThenExitsZero) {
  Child child = spawn({"--listen", "127.0.0.1:0", "--drain-deadline-ms", "10000", "--log-level", "warn"});
  const std::string address = listening_address(child);
  auto stub = v1::LipSync::NewStub(connect(address));
  const auto intervals = utterance(100, 8);
  const auto requests = chunked(intervals, 25);
  {
    Producer producer(*stub, {});
    producer.write(requests[0]);
    producer.read_frames(1);
    ASSERT_EQ(kill(child.pid, SIGTERM), 0);
    for (std::size_t i = 1; i < requests.size(); ++i) producer.write(requests[i]);
    producer.write(end_request());
    const Received received = producer.finish();
    ASSERT_TRUE(received.status.ok()) << received.status.error_message();
    expect_same(received.frames, reference_frames(intervals));
  }
  EXPECT_EQ(child.wait(), 0);
}

TEST(LipsyncdBinary, SigtermExitsAtOnceWhenNoCallIsRunningThoughClientsStayConnected) {
  Child child = spawn({"--listen", "127.0.0.1:0", "--drain-deadline-ms", "60000", "--log-level", "warn"});
  const std::string address = listening_address(child);
  auto channel = connect(address);
  auto stub = v1::LipSync::NewStub(channel);
  const auto intervals = utterance(20, 3);
  const Received received = animate(*stub, whole({}, intervals, 5));
  ASSERT_TRUE(received.status.ok()) << received.status.error_message();
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  // The drain deadline is a minute; with nothing running there is nothing to wait for.
  EXPECT_EQ(child.wait_for(std::chrono::seconds(20)), std::optional<int>(0));
}

/// A TCP connection to 127.0.0.1:`port` (-1 when refused).
int connect_tcp(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

/// A server on a free loopback port that logs warnings only.
ServerConfig quiet_loopback_config() {
  ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.log_level = "warn";
  return config;
}

bool accepts_connections(int port) {
  const int fd = connect_tcp(port);
  if (fd >= 0) ::close(fd);
  return fd >= 0;
}

// The drain closes the listener (and sends GOAWAY), so a balancer's new connection is refused and
// goes to another replica, while the streams already running finish.
TEST(ServerDrain, TheListenerClosesAndNewCallsAreRefusedWhileRunningStreamsFinish) {
  Server server(quiet_loopback_config());
  auto stub = v1::LipSync::NewStub(connect(server.address()));
  Producer running(*stub, {});  // keeps the drain waiting
  ASSERT_TRUE(accepts_connections(server.port()));
  std::thread drain([&] { server.shutdown(std::chrono::milliseconds(60'000)); });
  ASSERT_TRUE(eventually([&] { return !accepts_connections(server.port()); }));
  // A call on the old connection that races its GOAWAY may still be cancelled; once the GOAWAY
  // has arrived the client reconnects, is refused, and says UNAVAILABLE.
  EXPECT_TRUE(eventually([&] {
    return animate(*stub, whole({}, utterance(3, 4), 3)).status.error_code() == grpc::StatusCode::UNAVAILABLE;
  }));
  auto fresh = v1::LipSync::NewStub(connect(server.address()));
  EXPECT_EQ(animate(*fresh, whole({}, utterance(3, 4), 3)).status.error_code(), grpc::StatusCode::UNAVAILABLE);
  const auto intervals = utterance(10, 5);
  for (auto& request : chunked(intervals, 5)) running.write(request);
  running.write(end_request());
  const Received finished = running.finish();  // the running stream still completes
  EXPECT_TRUE(finished.status.ok()) << finished.status.error_message();
  drain.join();
}

// nginx opens one upstream connection per call and sends the call right after connecting. A
// connection the kernel completed just before the listener closed (in the accept backlog, or just
// accepted) is one the balancer counts as connected, so its call must be served, not refused or
// reset: the balancer would not retry it elsewhere. A second call on it is refused as on any
// connection that was open before the drain.
TEST(ServerDrain, TheFirstCallOfAConnectionCompletedAsTheListenerClosesIsServed) {
  Server server(quiet_loopback_config());
  auto stub = v1::LipSync::NewStub(connect(server.address()));
  Producer running(*stub, {});  // keeps the drain waiting
  const int just_connected = connect_tcp(server.port());
  ASSERT_GE(just_connected, 0);
  std::thread drain([&] { server.shutdown(std::chrono::milliseconds(60'000)); });
  ASSERT_TRUE(eventually([&] { return !accepts_connections(server.port()); }));
  auto late = v1::LipSync::NewStub(grpc::CreateInsecureChannelFromFd("late", just_connected));
  const auto intervals = utterance(8, 6);
  const Received first = animate(*late, whole({}, intervals, 4));
  ASSERT_TRUE(first.status.ok()) << first.status.error_message();
  expect_same(first.frames, reference_frames(intervals));
  EXPECT_EQ(animate(*late, whole({}, intervals, 4)).status.error_code(), grpc::StatusCode::UNAVAILABLE);
  running.write(end_request());
  EXPECT_TRUE(running.finish().status.ok());
  drain.join();
}

TEST(LipsyncdBinary, StreamsStillOpenAtTheDrainDeadlineAreCancelled) {
  Child child = spawn({"--listen", "127.0.0.1:0", "--drain-deadline-ms", "200", "--log-level", "off"});
  const std::string address = listening_address(child);
  auto stub = v1::LipSync::NewStub(connect(address));
  Producer producer(*stub, {});
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  EXPECT_EQ(child.wait(), 0);
  EXPECT_FALSE(producer.finish().status.ok());
}

}  // namespace
}  // namespace lipsync::server
