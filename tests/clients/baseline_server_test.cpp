// The bare gRPC server that the load tests measure lipsyncd against
// (tests/bench/grpc_baseline_server.cpp, docs/performance.md) is a reference only
// while it sends what lipsyncd sends and keeps sessions as lipsyncd does. Twice
// it did not: it released each phoneme's frames one phoneme late (fewer, larger
// batches: a cheaper reference), and it swept every session it held on each open
// (a longer tail with subscribers than lipsyncd's). These tests run the real
// baseline and the real lipsyncd on 127.0.0.1:0, drive both with the real
// `lipsync loadtest`, and pin what a fair comparison needs. The baseline's
// --busy-ns-per-frame, which adds a known amount of work per frame sent, is
// checked to spend it and to change nothing that is sent.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../support/child_process.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace lipsync {
namespace {

namespace fs = std::filesystem;
namespace v1 = lipsync::v1;
using testing::ChildProcess;
using testing::make_temp_dir;
using testing::read_text;
using namespace std::chrono_literals;

constexpr auto kRetention = 1000ms;

class BaselineServerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(make_temp_dir("baseline-server-test-"));
    baseline_ = new ChildProcess({GRPC_BASELINE_SERVER_BINARY, "--listen", "127.0.0.1:0", "--session-retention-ms",
                                  std::to_string(kRetention.count())},
                                 *dir_, *dir_ / "baseline.out", *dir_ / "baseline.err");
    lipsyncd_ = new ChildProcess({LIPSYNCD_BINARY, "--listen", "127.0.0.1:0", "--log-level", "warn"}, *dir_,
                                 *dir_ / "lipsyncd.out", *dir_ / "lipsyncd.err");
    baseline_address_ = new std::string(testing::wait_for_listening_address(*dir_ / "baseline.out", "listening on "));
    lipsyncd_address_ = new std::string(testing::wait_for_listening_address(*dir_ / "lipsyncd.out"));
  }
  static void TearDownTestSuite() {
    for (ChildProcess* server : {baseline_, lipsyncd_}) {
      server->terminate();
      server->wait();
      delete server;
    }
    fs::remove_all(*dir_);
    delete dir_;
    delete baseline_address_;
    delete lipsyncd_address_;
  }
  void SetUp() override {
    ASSERT_FALSE(baseline_address_->empty()) << "the baseline did not start: " << read_text(*dir_ / "baseline.err");
    ASSERT_FALSE(lipsyncd_address_->empty()) << "lipsyncd did not start: " << read_text(*dir_ / "lipsyncd.err");
  }

  /// `lipsync loadtest` against `address` with `options`, its JSON report (after checking that it
  /// exited 0: no errors, every frame arrived).
  static nlohmann::json loadtest(const std::string& address, std::vector<std::string> options) {
    std::vector<std::string> args = {LIPSYNC_CLI_BINARY, "loadtest", "--server", address, "--json"};
    args.insert(args.end(), options.begin(), options.end());
    ChildProcess run(args, *dir_, *dir_ / "loadtest.out", *dir_ / "loadtest.err");
    const int status = run.wait();
    const std::string out = read_text(*dir_ / "loadtest.out");
    EXPECT_EQ(status, 0) << out << read_text(*dir_ / "loadtest.err");
    return nlohmann::json::parse(out);
  }

  static std::unique_ptr<v1::LipSync::Stub> baseline_stub() {
    return v1::LipSync::NewStub(grpc::CreateChannel(*baseline_address_, grpc::InsecureChannelCredentials()));
  }

  static fs::path* dir_;
  static ChildProcess* baseline_;
  static ChildProcess* lipsyncd_;
  static std::string* baseline_address_;
  static std::string* lipsyncd_address_;
};

fs::path* BaselineServerTest::dir_ = nullptr;
ChildProcess* BaselineServerTest::baseline_ = nullptr;
ChildProcess* BaselineServerTest::lipsyncd_ = nullptr;
std::string* BaselineServerTest::baseline_address_ = nullptr;
std::string* BaselineServerTest::lipsyncd_address_ = nullptr;

/// Per utterance, what one server sent its producers.
struct PerUtterance {
  double frames;
  double batches;
};

PerUtterance per_utterance(const nlohmann::json& report) {
  const auto utterances = report["utterances"]["complete"].get<double>();
  EXPECT_GT(utterances, 0.0);
  return {report["frames"]["producers"].get<double>() / utterances,
          report["batches"]["producers"].get<double>() / utterances};
}

TEST_F(BaselineServerTest, SendsAsManyFramesAndBatchesPerUtteranceAsLipsyncd) {
  const std::vector<std::string> load = {"--fast", "--producers", "4", "--duration", "2", "--seed", "7"};
  const PerUtterance lipsyncd = per_utterance(loadtest(*lipsyncd_address_, load));
  std::vector<std::string> unverified = load;
  unverified.push_back("--no-verify");
  const PerUtterance baseline = per_utterance(loadtest(*baseline_address_, unverified));
  // The same utterances give the same frames, give or take lipsyncd's key frames (about 1.5 %
  // fewer frames: no uniform frame inside a closure).
  EXPECT_NEAR(baseline.frames / lipsyncd.frames, 1.0, 0.04)
      << "frames per utterance: baseline " << baseline.frames << ", lipsyncd " << lipsyncd.frames;
  // Released at the same phoneme, so in as many batches, less the few that lipsyncd's key frames
  // add (about 2.6 %). A baseline that released one phoneme late sent 6.6 % fewer, below 0.95.
  EXPECT_GE(baseline.batches / lipsyncd.batches, 0.95)
      << "batches per utterance: baseline " << baseline.batches << ", lipsyncd " << lipsyncd.batches;
  EXPECT_LE(baseline.batches / lipsyncd.batches, 1.01)
      << "batches per utterance: baseline " << baseline.batches << ", lipsyncd " << lipsyncd.batches;
}

TEST_F(BaselineServerTest, EverySubscriberReceivesExactlyWhatItsProducerReceives) {
  const nlohmann::json report = loadtest(
      *baseline_address_, {"--producers", "20", "--subscribers-per-session", "1", "--duration", "2", "--no-verify"});
  EXPECT_TRUE(report["errors"].empty()) << report.dump();
  EXPECT_GT(report["subscriptions"]["complete"].get<int>(), 0);
  EXPECT_EQ(report["frames"]["subscribers"], report["frames"]["producers"]);
  EXPECT_EQ(report["batches"]["subscribers"], report["batches"]["producers"]);
}

/// One utterance of `phonemes` phonemes of 100 ms streamed to the baseline under `session`; the
/// messages the producer received, serialised.
std::vector<std::string> produce_messages(v1::LipSync::Stub& stub, const std::string& session, int phonemes) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  auto stream = stub.Animate(&context);
  v1::AnimateRequest request;
  request.mutable_settings()->set_session(session);
  EXPECT_TRUE(stream->Write(request));
  request.Clear();
  for (int i = 0; i < phonemes; ++i) {
    v1::Phoneme& phoneme = *request.mutable_phonemes()->add_phonemes();
    phoneme.set_label("aa");
    phoneme.set_start_us(i * 100'000);
    phoneme.set_end_us((i + 1) * 100'000);
  }
  EXPECT_TRUE(stream->Write(request));
  request.Clear();
  request.mutable_end();
  EXPECT_TRUE(stream->Write(request));
  stream->WritesDone();
  std::vector<std::string> messages;
  v1::TrackMessage message;
  while (stream->Read(&message)) messages.push_back(message.SerializeAsString());
  const grpc::Status status = stream->Finish();
  EXPECT_TRUE(status.ok()) << status.error_message();
  return messages;
}

/// The same, how many messages there were.
std::size_t produce(v1::LipSync::Stub& stub, const std::string& session, int phonemes) {
  return produce_messages(stub, session, phonemes).size();
}

struct Subscription {
  grpc::StatusCode code;
  std::size_t messages;
};

Subscription subscribe(v1::LipSync::Stub& stub, const std::string& session) {
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + 10s);
  v1::SubscribeRequest request;
  request.set_session(session);
  auto reader = stub.Subscribe(&context, request);
  std::size_t messages = 0;
  v1::TrackMessage message;
  while (reader->Read(&message)) ++messages;
  return {reader->Finish().error_code(), messages};
}

TEST_F(BaselineServerTest, KeepsAnEndedSessionForTheRetentionAndThenForgetsIt) {
  auto stub = baseline_stub();
  const std::size_t sent = produce(*stub, "kept", 20);
  // Header, batches, summary: 20 phonemes of 100 ms at 30 fps release frames in several batches.
  EXPECT_GE(sent, 4u);
  const Subscription late = subscribe(*stub, "kept");
  EXPECT_EQ(late.code, grpc::StatusCode::OK);
  EXPECT_EQ(late.messages, sent) << "a subscriber after the end gets every message from the start";

  // A session that opens within the retention forgets nothing.
  std::this_thread::sleep_for(kRetention / 2);
  produce(*stub, "within", 2);
  const Subscription still = subscribe(*stub, "kept");
  EXPECT_EQ(still.code, grpc::StatusCode::OK);
  EXPECT_EQ(still.messages, sent);

  std::this_thread::sleep_for(kRetention / 2 + 200ms);
  // Expired sessions are forgotten when the next one opens.
  produce(*stub, "next", 2);
  EXPECT_EQ(subscribe(*stub, "kept").code, grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(subscribe(*stub, "next").code, grpc::StatusCode::OK);
}

TEST_F(BaselineServerTest, ANameOpenedAgainIsNotForgottenWithItsEarlierSession) {
  auto stub = baseline_stub();
  produce(*stub, "again", 2);
  std::this_thread::sleep_for(kRetention / 2);
  const std::size_t second = produce(*stub, "again", 12);
  // The first "again" expires now, the second not for another half retention.
  std::this_thread::sleep_for(kRetention / 2 + 100ms);  // the second has 400 ms to go
  produce(*stub, "opener", 2);
  const Subscription found = subscribe(*stub, "again");
  EXPECT_EQ(found.code, grpc::StatusCode::OK);
  EXPECT_EQ(found.messages, second);
}

/// The user and system CPU time `pid` has spent, from /proc/PID/stat (fields 14 and 15, after
/// the command name in parentheses).
std::chrono::duration<double> cpu_time(pid_t pid) {
  std::ifstream file("/proc/" + std::to_string(pid) + "/stat");
  std::string stat((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  std::istringstream fields(stat.substr(stat.rfind(')') + 2));
  std::string field;
  for (int i = 3; i < 14; ++i) fields >> field;  // state (field 3) to cmajflt (field 13)
  long user_ticks = 0;
  long system_ticks = 0;
  fields >> user_ticks >> system_ticks;
  return std::chrono::duration<double>(static_cast<double>(user_ticks + system_ticks) /
                                       static_cast<double>(::sysconf(_SC_CLK_TCK)));
}

TEST_F(BaselineServerTest, SpendsItsBusyTimePerFrameAndSendsTheSameMessages) {
  // 1 ms per frame: 60 phonemes of 100 ms are 180 frames at 30 fps, 180 ms of spinning.
  ChildProcess busy({GRPC_BASELINE_SERVER_BINARY, "--listen", "127.0.0.1:0", "--busy-ns-per-frame", "1000000"}, *dir_,
                    *dir_ / "busy.out", *dir_ / "busy.err");
  const std::string address = testing::wait_for_listening_address(*dir_ / "busy.out", "listening on ");
  ASSERT_FALSE(address.empty()) << read_text(*dir_ / "busy.err");
  auto busy_stub = v1::LipSync::NewStub(grpc::CreateChannel(address, grpc::InsecureChannelCredentials()));
  const auto before = cpu_time(busy.pid());
  const std::vector<std::string> busy_messages = produce_messages(*busy_stub, "busy check", 60);
  const auto spent = cpu_time(busy.pid()) - before;
  busy.terminate();
  EXPECT_EQ(busy.wait(), 0);

  const std::vector<std::string> messages = produce_messages(*baseline_stub(), "busy check", 60);
  EXPECT_GE(messages.size(), 4u);
  EXPECT_TRUE(busy_messages == messages) << "the busy baseline sent other messages (" << busy_messages.size()
                                         << " against " << messages.size() << ")";
  // The spin is on the clock, so a core shared with other work gives it less CPU; a quarter of it
  // still tells it apart from the few milliseconds the stream costs without it.
  EXPECT_GE(spent.count(), 0.045) << "CPU spent on 180 frames with 1 ms of work each";
}

TEST(BaselineServerOptions, ABadValueExits2AndNamesTheOption) {
  const fs::path dir = make_temp_dir("baseline-options-test-");
  for (const std::vector<std::string>& args :
       std::vector<std::vector<std::string>>{{"--busy-ns-per-frame", "-1"},
                                             {"--busy-ns-per-frame", "1000001"},
                                             {"--busy-ns-per-frame", "12x"},
                                             {"--session-retention-ms", "86400001"},
                                             {"--busy-ns-per-frame"}}) {
    std::vector<std::string> argv = {GRPC_BASELINE_SERVER_BINARY};
    argv.insert(argv.end(), args.begin(), args.end());
    ChildProcess run(argv, dir, dir / "out", dir / "err");
    EXPECT_EQ(run.wait(), 2) << args.front();
    EXPECT_NE(read_text(dir / "err").find(args.front()), std::string::npos) << read_text(dir / "err");
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lipsync
