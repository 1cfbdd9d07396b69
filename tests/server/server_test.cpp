// lipsyncd over the network: Animate equals Render equals render_track, fan-out
// to many subscribers, a slow subscriber cut off without hurting the others,
// replay, cancellation, validation errors, limits, models, health, and the
// binary's flags, exit codes and SIGTERM drain.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <future>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

#include <grpcpp/generic/generic_stub.h>
#include <grpcpp/grpcpp.h>

#include "lipsync/error.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/server/config.hpp"
#include "lipsync/server/server.hpp"
#include "lipsync/synthetic.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace lipsync::server {
namespace {

using ::testing::HasSubstr;
using namespace std::chrono_literals;

constexpr auto kCallTimeout = 20s;

// --- the expected frames, from the core engine directly --------------------

struct Frames {
  std::vector<std::int64_t> t_us;
  std::vector<int> kinds;
  std::vector<float> values;
  std::vector<float> arkit;
  std::uint64_t first_frame = 0;

  void append(const v1::FrameBatch& batch) {
    if (t_us.empty()) first_frame = batch.first_frame();
    t_us.insert(t_us.end(), batch.t_us().begin(), batch.t_us().end());
    kinds.insert(kinds.end(), batch.kinds().begin(), batch.kinds().end());
    values.insert(values.end(), batch.values().begin(), batch.values().end());
    arkit.insert(arkit.end(), batch.arkit().begin(), batch.arkit().end());
  }
};

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

std::vector<LabeledInterval> utterance(std::size_t phonemes, std::uint64_t seed = 1) {
  return synthesize_utterance({.phonemes = phonemes, .seed = seed});
}

v1::Phoneme to_proto(const LabeledInterval& interval) {
  v1::Phoneme phoneme;
  phoneme.set_label(interval.label);
  phoneme.set_start_us(interval.start_us);
  phoneme.set_end_us(interval.end_us);
  return phoneme;
}

v1::Phoneme phoneme(const std::string& label, std::int64_t start_us, std::int64_t end_us) {
  return to_proto({label, start_us, end_us, 0});
}

// --- requests -----------------------------------------------------------------

v1::AnimateRequest settings_request(v1::AnimationSettings settings = {}) {
  v1::AnimateRequest request;
  *request.mutable_settings() = std::move(settings);
  return request;
}

v1::AnimateRequest chunk_request(const std::vector<v1::Phoneme>& phonemes) {
  v1::AnimateRequest request;
  for (const auto& p : phonemes) *request.mutable_phonemes()->add_phonemes() = p;
  return request;
}

v1::AnimateRequest end_request() {
  v1::AnimateRequest request;
  request.mutable_end();
  return request;
}

std::vector<v1::AnimateRequest> chunked(const std::vector<LabeledInterval>& intervals, std::size_t chunk) {
  std::vector<v1::AnimateRequest> requests;
  for (std::size_t i = 0; i < intervals.size(); i += chunk) {
    std::vector<v1::Phoneme> phonemes;
    for (std::size_t j = i; j < std::min(intervals.size(), i + chunk); ++j) phonemes.push_back(to_proto(intervals[j]));
    requests.push_back(chunk_request(phonemes));
  }
  return requests;
}

// --- what a stream delivered ---------------------------------------------------

struct Received {
  std::optional<v1::TrackHeader> header;
  Frames frames;
  std::optional<v1::TrackSummary> summary;
  std::size_t batches = 0;
  grpc::Status status;
};

void take(Received& received, const v1::TrackMessage& message) {
  if (message.has_header()) received.header = message.header();
  if (message.has_frames()) {
    received.frames.append(message.frames());
    ++received.batches;
  }
  if (message.has_summary()) received.summary = message.summary();
}

template <class Reader>
void read_all(Reader& reader, Received& received) {
  v1::TrackMessage message;
  while (reader.Read(&message)) take(received, message);
}

void set_deadline(grpc::ClientContext& context) { context.set_deadline(std::chrono::system_clock::now() + kCallTimeout); }

std::shared_ptr<grpc::Channel> connect(const std::string& address, bool bdp_probe = true) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);
  if (!bdp_probe) args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

/// One Animate call: writes `requests` (then WritesDone) while another thread reads.
Received animate(v1::LipSync::Stub& stub, const std::vector<v1::AnimateRequest>& requests) {
  grpc::ClientContext context;
  set_deadline(context);
  auto stream = stub.Animate(&context);
  Received received;
  std::thread reader([&] { read_all(*stream, received); });
  for (const auto& request : requests) {
    if (!stream->Write(request)) break;
  }
  stream->WritesDone();
  reader.join();
  received.status = stream->Finish();
  return received;
}

std::vector<v1::AnimateRequest> whole(const v1::AnimationSettings& settings,
                                      const std::vector<LabeledInterval>& intervals, std::size_t chunk) {
  std::vector<v1::AnimateRequest> requests{settings_request(settings)};
  for (auto& request : chunked(intervals, chunk)) requests.push_back(std::move(request));
  requests.push_back(end_request());
  return requests;
}

Received subscribe_all(v1::LipSync::Stub& stub, const std::string& session,
                       v1::SubscribeRequest::Start start = v1::SubscribeRequest::START_FROM_BEGINNING) {
  grpc::ClientContext context;
  set_deadline(context);
  v1::SubscribeRequest request;
  request.set_session(session);
  request.set_start(start);
  auto reader = stub.Subscribe(&context, request);
  Received received;
  read_all(*reader, received);
  received.status = reader->Finish();
  return received;
}

template <class Condition>
bool eventually(Condition condition) {
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

// --- the fixture: a real server on 127.0.0.1:0 --------------------------------

class ServerTest : public ::testing::Test {
 protected:
  void start(ServerConfig config = {}) {
    config.listen = "127.0.0.1:0";
    config.log_level = "warn";
    server_ = std::make_unique<Server>(config);
    channel_ = connect(server_->address());
    stub_ = v1::LipSync::NewStub(channel_);
  }
  void SetUp() override { start(); }
  void TearDown() override {
    if (server_) server_->shutdown(0ms);
  }

  std::unique_ptr<Server> server_;
  std::shared_ptr<grpc::Channel> channel_;
  std::unique_ptr<v1::LipSync::Stub> stub_;
};

// A producer stream driven step by step from the test.
class Producer {
 public:
  Producer(v1::LipSync::Stub& stub, v1::AnimationSettings settings) {
    set_deadline(context_);
    stream_ = stub.Animate(&context_);
    EXPECT_TRUE(stream_->Write(settings_request(std::move(settings))));
    v1::TrackMessage message;
    EXPECT_TRUE(stream_->Read(&message));
    take(received_, message);
    EXPECT_TRUE(received_.header.has_value());
  }
  void write(const v1::AnimateRequest& request) { EXPECT_TRUE(stream_->Write(request)); }
  /// Reads until at least `frames` frames have arrived.
  void read_frames(std::size_t frames) {
    v1::TrackMessage message;
    while (received_.frames.t_us.size() < frames && stream_->Read(&message)) take(received_, message);
  }
  void read_message() {
    v1::TrackMessage message;
    if (stream_->Read(&message)) take(received_, message);
  }
  Received finish() {
    stream_->WritesDone();
    read_all(*stream_, received_);
    received_.status = stream_->Finish();
    return received_;
  }
  void cancel() { context_.TryCancel(); }

 private:
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReaderWriter<v1::AnimateRequest, v1::TrackMessage>> stream_;
  Received received_;
};

// A subscriber that has seen its header (so it is attached) and reads on demand.
class Subscriber {
 public:
  Subscriber(v1::LipSync::Stub& stub, const std::string& session, v1::SubscribeRequest::Start start) {
    set_deadline(context_);
    v1::SubscribeRequest request;
    request.set_session(session);
    request.set_start(start);
    reader_ = stub.Subscribe(&context_, request);
    v1::TrackMessage message;
    if (reader_->Read(&message)) take(received_, message);
  }
  bool attached() const { return received_.header.has_value(); }
  Received finish() {
    read_all(*reader_, received_);
    received_.status = reader_->Finish();
    return received_;
  }

 private:
  grpc::ClientContext context_;
  std::unique_ptr<grpc::ClientReader<v1::TrackMessage>> reader_;
  Received received_;
};

v1::AnimationSettings session_settings(const std::string& session) {
  v1::AnimationSettings settings;
  settings.set_session(session);
  settings.mutable_media_clock()->set_clock("unix");
  settings.mutable_media_clock()->set_utterance_zero_us(1'700'000'000'000'000);
  return settings;
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

TEST_F(ServerTest, ASlowSubscriberIsCutOffWhileTheOthersFinish) {
  ServerConfig config;
  config.subscriber_queue_frames = 4000;
  config.replay_frames = 64;
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
      {"unknown label", {settings_request(), chunk_request({aa, phoneme("XQ", 100'000, 200'000)}), end_request()},
       "phoneme stream:2: phoneme 'XQ'"},
      {"reversed times", {settings_request(), chunk_request({aa, phoneme("B", 300'000, 200'000)}), end_request()},
       "phoneme stream:2:"},
      {"overlap", {settings_request(), chunk_request({aa, phoneme("B", 50'000, 200'000)}), end_request()},
       "phoneme stream:2:"},
      {"backwards across chunks",
       {settings_request(), chunk_request({aa, phoneme("B", 100'000, 200'000)}),
        chunk_request({phoneme("K", 150'000, 250'000)}), end_request()},
       "phoneme stream:3:"},
      {"missing settings", {chunk_request({aa}), end_request()}, "first message must be settings"},
      {"second settings", {settings_request(), chunk_request({aa}), settings_request(), end_request()},
       "settings sent twice"},
      {"phoneme after end", {settings_request(), chunk_request({aa}), end_request(), chunk_request({phoneme("B", 100'000, 200'000)})},
       "phoneme stream:2: phoneme 'B': received after `end`"},
      {"fps", {settings_request(with([](auto& s) { s.set_fps(241); }))}, "settings.fps"},
      {"lookahead", {settings_request(with([](auto& s) { s.set_lookahead(8); }))}, "settings.lookahead"},
      {"phone set", {settings_request(with([](auto& s) { s.set_phone_set("klingon"); }))}, "settings.phone_set"},
      {"model", {settings_request(with([](auto& s) { s.set_model("nope"); }))}, "settings.model"},
      {"closure fraction", {settings_request(with([](auto& s) { s.set_closure_fraction(1.5); }))},
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

struct Child {
  pid_t pid = -1;
  FILE* out = nullptr;

  std::string line() {
    char* buffer = nullptr;
    std::size_t size = 0;
    const auto read = getline(&buffer, &size, out);
    std::string text = read > 0 ? std::string(buffer, static_cast<std::size_t>(read)) : std::string();
    free(buffer);
    return text;
  }
  int wait() {
    int status = 0;
    waitpid(pid, &status, 0);
    if (out) fclose(out);
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
};

Child spawn(std::vector<std::string> args) {
  int pipe_fds[2];
  EXPECT_EQ(pipe(pipe_fds), 0);
  args.insert(args.begin(), LIPSYNCD_PATH);
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(pipe_fds[1], STDOUT_FILENO);
    close(pipe_fds[0]);
    close(pipe_fds[1]);
    std::vector<char*> argv;
    for (auto& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  close(pipe_fds[1]);
  return {pid, fdopen(pipe_fds[0], "r")};
}

std::string listening_address(Child& child) {
  const std::string line = child.line();
  const std::string prefix = "lipsyncd listening on ";
  EXPECT_EQ(line.rfind(prefix, 0), 0u) << line;
  return line.substr(prefix.size(), line.find_last_not_of("\r\n") + 1 - prefix.size());
}

TEST(LipsyncdBinary, BadFlagsExit2AndABadModelExits1) {
  EXPECT_EQ(spawn({"--max-streams", "-3"}).wait(), 2);
  EXPECT_EQ(spawn({"--no-such-flag"}).wait(), 2);
  EXPECT_EQ(spawn({"--listen", "127.0.0.1:0", "--model", "bad=" LIPSYNC_TEST_DATA_DIR "/models/bad_alpha.json"}).wait(), 1);
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
