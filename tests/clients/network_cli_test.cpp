// End-to-end tests of the network commands: the real lipsyncd (started once
// for the suite on 127.0.0.1:0, its port read from its "listening on" line)
// and the real `lipsync` binary, run in a fresh directory per test. Besides
// the built-in model the server loads "renamed": the built-in model with every
// channel called alt_<name>, so its frames equal the built-in model's and only
// the names tell which model's layout a client wrote.
#include <arpa/inet.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../support/child_process.hpp"

namespace lipsync {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using testing::make_temp_dir;
using testing::read_text;

const fs::path kFixtures = fs::path(LIPSYNC_TEST_DATA_DIR) / "cli";
constexpr std::string_view kRenamedPrefix = "alt_";

/// The built-in model with every channel called alt_<name> (and the model "renamed").
std::string renamed_model_json() {
  auto model = nlohmann::json::parse(read_text(fs::path(LIPSYNC_SOURCE_DIR) / "data/models/default.json"));
  const auto rename_keys = [](nlohmann::json& object) {
    nlohmann::json renamed = nlohmann::json::object();
    for (auto& [key, value] : object.items()) renamed[std::string(kRenamedPrefix) + key] = value;
    object = renamed;
  };
  model["name"] = "renamed";
  for (auto& channel : model["channels"])
    channel["name"] = std::string(kRenamedPrefix) + channel["name"].get<std::string>();
  for (auto& [name, phoneme] : model["phonemes"].items()) {
    for (const char* field : {"targets", "channel_dominance"}) {
      if (phoneme.contains(field)) rename_keys(phoneme[field]);
    }
  }
  for (auto& [name, shape] : model["arkit"].items()) rename_keys(shape["weights"]);
  return model.dump(2);
}

/// `text`, a track of the built-in model as `render` writes it, as the renamed model's
/// track reads: json names the model "renamed" and its channels alt_*, csv its columns.
std::string as_renamed(std::string text, const std::string& format) {
  const auto rename_list = [&](std::size_t from, std::size_t to, char quote_or_comma) {
    std::string renamed = text.substr(0, from);
    for (std::size_t i = from; i < to; ++i) {
      renamed += text[i];
      if (text[i] == quote_or_comma && (quote_or_comma != '"' || text[i - 1] == '[' || text[i - 1] == ',')) {
        renamed += kRenamedPrefix;
      }
    }
    return renamed + text.substr(to);
  };
  if (format == "csv") {
    // "t,t_us,kind,a,b" → "t,t_us,kind,alt_a,alt_b"
    const std::size_t start = std::string("t,t_us,kind").size();
    return rename_list(start, text.find('\n'), ',');
  }
  const std::string model = "\"model\":\"default\"";
  text.replace(text.find(model), model.size(), "\"model\":\"renamed\"");
  const std::size_t channels = text.find("\"channels\":[") + std::string("\"channels\":[").size() - 1;
  return rename_list(channels + 1, text.find(']', channels), '"');
}

/// A loopback port that nothing listens on (bound, read, closed).
int unused_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof address;
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&address), size) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size) != 0) {
    throw std::runtime_error("cannot find an unused port");
  }
  ::close(fd);
  return ntohs(address.sin_port);
}

/// What `lipsync play` says when it stops: underruns, worst lateness and the playout offset it chose.
struct PlaySummary {
  long underruns = -1;
  std::optional<long> max_lateness_ms;
  long playout_offset_ms = -1;
  long release_delay_ms = -1;
  long max_release_lag_ms = -1;
  std::string out;  ///< everything play printed
};

PlaySummary parse_play_summary(const std::string& out) {
  static const std::regex summary(
      R"((\d+) underruns, max behind -?\d+ ms, max lateness (-?\d+ ms|-), playout offset (\d+) ms \(release delay )"
      R"((\d+) ms, max release lag (-?\d+) ms\))");
  std::smatch match;
  PlaySummary parsed;
  parsed.out = out;
  if (!std::regex_search(out, match, summary)) return parsed;
  parsed.underruns = std::stol(match[1]);
  if (match[2] != "-") parsed.max_lateness_ms = std::stol(match[2]);
  parsed.playout_offset_ms = std::stol(match[3]);
  parsed.release_delay_ms = std::stol(match[4]);
  parsed.max_release_lag_ms = std::stol(match[5]);
  return parsed;
}

using testing::ChildProcess;
using testing::RunResult;

class NetworkCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    server_dir_ = new fs::path(make_temp_dir("lipsyncd-test-"));
    testing::write_text(*server_dir_ / "renamed.json", renamed_model_json());
    server_ = new ChildProcess(
        {LIPSYNCD_BINARY, "--listen", "127.0.0.1:0", "--max-sessions", "5000", "--session-retention-ms", "5000",
         "--model", "renamed=" + (*server_dir_ / "renamed.json").string(), "--log-level", "warn",
         // Face threads that compete normally: with ctest -j2 an idle-priority
         // face could wait for the other test to finish.
         "--face-priority", "normal"},
        *server_dir_, *server_dir_ / "stdout", *server_dir_ / "stderr");
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    const std::string prefix = "lipsyncd listening on ";
    while (std::chrono::steady_clock::now() < give_up) {
      const std::string out = read_text(*server_dir_ / "stdout");
      if (const auto at = out.find(prefix); at != std::string::npos && out.find('\n', at) != std::string::npos) {
        address_ = new std::string(out.substr(at + prefix.size(), out.find('\n', at) - at - prefix.size()));
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  static void TearDownTestSuite() {
    server_->terminate();
    server_->wait();
    delete server_;
    fs::remove_all(*server_dir_);
    delete server_dir_;
    delete address_;
  }

  void SetUp() override {
    ASSERT_NE(address_, nullptr) << "lipsyncd did not start: " << read_text(*server_dir_ / "stderr");
    dir_ = make_temp_dir("lipsync-net-test-");
    capture_ = make_temp_dir("lipsync-net-capture-");
  }
  void TearDown() override {
    fs::remove_all(dir_);
    fs::remove_all(capture_);
  }

  std::unique_ptr<ChildProcess> start(std::vector<std::string> args, const std::string& name) {
    args.insert(args.begin(), LIPSYNC_CLI_BINARY);
    return std::make_unique<ChildProcess>(std::move(args), dir_, capture_ / (name + ".out"),
                                          capture_ / (name + ".err"));
  }
  RunResult run(const std::vector<std::string>& args, const std::string& name = "run") {
    RunResult result;
    result.status = start(args, name)->wait();
    result.out = read_text(capture_ / (name + ".out"));
    result.err = read_text(capture_ / (name + ".err"));
    return result;
  }
  std::string output(const std::string& name) { return read_text(dir_ / name); }

  static std::string fixture(std::string_view name) { return (kFixtures / name).string(); }
  static const std::string& server() { return *address_; }

  /// `lipsync stream --realtime` of real read speech (flite's timing of a 2 s sentence from
  /// tests/data/closures) with `stream_options`, followed by `lipsync play`: its summary, after
  /// checking that both exited 0 and that no frame was late (no underrun, lateness always < 0).
  PlaySummary play_real_speech_without_late_frames(const std::string& file, const std::string& session,
                                                   const std::vector<std::string>& stream_options) {
    std::vector<std::string> stream = {"stream",     (fs::path(LIPSYNC_TEST_DATA_DIR) / "closures" / file).string(),
                                       "--realtime", "--session",
                                       session,      "--server",
                                       server(),     "-o",
                                       "stream.json"};
    stream.insert(stream.end(), stream_options.begin(), stream_options.end());
    auto producer = start(stream, "producer");
    const RunResult played = run({"play", session, "--wait", "5", "--no-tty", "--server", server()});
    EXPECT_EQ(producer->wait(), 0) << read_text(capture_ / "producer.err");
    EXPECT_EQ(played.status, 0) << played.err;
    const PlaySummary summary = parse_play_summary(played.out);
    EXPECT_EQ(summary.underruns, 0) << played.out;
    EXPECT_TRUE(summary.max_lateness_ms.has_value() && *summary.max_lateness_ms < 0) << played.out;
    return summary;
  }

  static ChildProcess* server_;
  static fs::path* server_dir_;
  static std::string* address_;
  fs::path dir_;
  fs::path capture_;
};

ChildProcess* NetworkCliTest::server_ = nullptr;
fs::path* NetworkCliTest::server_dir_ = nullptr;
std::string* NetworkCliTest::address_ = nullptr;

TEST_F(NetworkCliTest, StreamEqualsRenderByteForByteInEveryFormat) {
  for (const std::string format : {"json", "csv", "arkit-csv"}) {
    for (const std::string input : {"hello.json", "bump_map.TextGrid"}) {
      const RunResult rendered = run({"render", fixture(input), "--format", format, "-o", "render.out"});
      ASSERT_EQ(rendered.status, 0) << rendered.err;
      const RunResult streamed =
          run({"stream", fixture(input), "--fast", "--server", server(), "--format", format, "-o", "stream.out"});
      ASSERT_EQ(streamed.status, 0) << streamed.err;
      EXPECT_EQ(output("stream.out"), output("render.out")) << input << " as " << format;
    }
  }
}

TEST_F(NetworkCliTest, RealtimeStreamInChunksEqualsRender) {
  ASSERT_EQ(run({"render", fixture("hello.json"), "-o", "render.json"}).status, 0);
  const RunResult streamed =
      run({"stream", fixture("hello.json"), "--realtime", "--chunk", "3", "--server", server(), "-o", "stream.json"});
  ASSERT_EQ(streamed.status, 0) << streamed.err;
  EXPECT_EQ(output("stream.json"), output("render.json"));
}

TEST_F(NetworkCliTest, SubscriberReceivesTheFramesOfARealtimeStream) {
  ASSERT_EQ(run({"render", fixture("hello.json"), "-o", "render.json"}).status, 0);
  auto producer =
      start({"stream", fixture("hello.json"), "--session", "subscribe-test", "--server", server(), "-o", "stream.json"},
            "producer");
  const RunResult subscribed =
      run({"subscribe", "subscribe-test", "--wait", "5", "--server", server(), "-o", "subscribe.json"});
  ASSERT_EQ(producer->wait(), 0) << read_text(capture_ / "producer.err");
  ASSERT_EQ(subscribed.status, 0) << subscribed.err;
  EXPECT_EQ(output("subscribe.json"), output("render.json"));
  EXPECT_EQ(output("stream.json"), output("render.json"));
}

TEST_F(NetworkCliTest, PlayPrintsALinePerUpdateUntilTheSessionEnds) {
  auto producer = start({"stream", fixture("hello.json"), "--session", "play-test", "--playout-delay", "300",
                         "--server", server(), "-o", "stream.json"},
                        "producer");
  const RunResult played = run({"play", "play-test", "--wait", "5", "--no-tty", "--rate", "20", "--server", server()});
  ASSERT_EQ(producer->wait(), 0);
  ASSERT_EQ(played.status, 0) << played.err;
  EXPECT_THAT(played.out, HasSubstr("jaw |"));
  EXPECT_THAT(played.out, HasSubstr("anchored to media clock 'unix'"));
  EXPECT_GT(std::count(played.out.begin(), played.out.end(), '\n'), 10);
}

TEST_F(NetworkCliTest, PlayOfRealSpeechStreamedInRealTimeHasNoLateFrameAtTheDefaults) {
  const PlaySummary summary = play_real_speech_without_late_frames("flite_1.psdur", "play-real-speech", {});
  // The producer's default delay covers the lookahead: played on its media clock, no offset.
  EXPECT_EQ(summary.playout_offset_ms, 0) << summary.out;
  // The server really made frames wait for the 7 segments ahead (else nothing was shown).
  EXPECT_GT(summary.max_release_lag_ms, 300) << summary.out;
  EXPECT_LE(summary.max_release_lag_ms, summary.release_delay_ms) << summary.out;
}

TEST_F(NetworkCliTest, PlayDelaysItselfWhenTheProducersPlayoutDelayIsShorterThanTheReleaseDelay) {
  const PlaySummary summary =
      play_real_speech_without_late_frames("flite_2.psdur", "play-short-delay", {"--playout-delay", "200"});
  // 200 ms cannot cover a wait of over a second: the player adds the difference.
  EXPECT_GT(summary.playout_offset_ms, summary.release_delay_ms - 200) << summary.out;
}

TEST_F(NetworkCliTest, PlayStopsAfterTheRequestedNumberOfUpdates) {
  auto producer = start(
      {"stream", fixture("hello.json"), "--session", "play-frames-test", "--server", server(), "-o", "stream.json"},
      "producer");
  const RunResult played = run(
      {"play", "play-frames-test", "--wait", "5", "--no-tty", "--frames", "3", "--rate", "50", "--server", server()});
  ASSERT_EQ(producer->wait(), 0);
  ASSERT_EQ(played.status, 0) << played.err;
  EXPECT_EQ(std::count(played.out.begin(), played.out.end(), '\n'), 4) << played.out;
}

TEST_F(NetworkCliTest, ARejectedStreamExits1WithTheServersReasonAndLeavesNoFile) {
  const RunResult streamed =
      run({"stream", fixture("unknown_label.json"), "--fast", "--server", server(), "-o", "out.json"});
  EXPECT_EQ(streamed.status, 1);
  EXPECT_THAT(streamed.err, HasSubstr("INVALID_ARGUMENT"));
  EXPECT_THAT(fs::directory_iterator(dir_) == fs::directory_iterator(), true);
}

TEST_F(NetworkCliTest, StreamAttachesAWavToItsSessionAndRefusesOneWithoutASessionOrNotAWav) {
  const std::string wav = (fs::path(LIPSYNC_TEST_DATA_DIR) / "speech" / "mono16.wav").string();
  const RunResult attached = run({"stream", fixture("hello.json"), "--fast", "--session", "cli-with-sound", "--audio",
                                  wav, "--server", server(), "-o", "with.json"});
  EXPECT_EQ(attached.status, 0) << attached.err;
  const RunResult plain = run({"stream", fixture("hello.json"), "--fast", "--server", server(), "-o", "without.json"});
  EXPECT_EQ(plain.status, 0) << plain.err;
  EXPECT_EQ(output("with.json"), output("without.json"));  // the frames do not depend on the sound

  const RunResult no_session = run({"stream", fixture("hello.json"), "--fast", "--audio", wav, "--server", server()});
  EXPECT_EQ(no_session.status, 2);
  EXPECT_THAT(no_session.err, HasSubstr("--audio needs --session"));
  const RunResult not_wav = run({"stream", fixture("hello.json"), "--fast", "--session", "cli-not-wav", "--audio",
                                 fixture("hello.json"), "--server", server()});
  EXPECT_EQ(not_wav.status, 1);
  EXPECT_THAT(not_wav.err, HasSubstr("hello.json: not a WAV file"));
}

TEST_F(NetworkCliTest, NetworkFailuresExit1AndUsageErrorsExit2) {
  const RunResult unknown_session = run({"subscribe", "no-such-session", "--server", server(), "-o", "out.json"});
  EXPECT_EQ(unknown_session.status, 1);
  EXPECT_THAT(unknown_session.err, HasSubstr("NOT_FOUND"));
  EXPECT_FALSE(fs::exists(dir_ / "out.json"));

  EXPECT_EQ(run({"stream", fixture("hello.json"), "--fast", "--realtime"}).status, 2);
  const RunResult remote = run({"loadtest", "--server", "192.0.2.1:50051"});
  EXPECT_EQ(remote.status, 2);
  EXPECT_THAT(remote.err, HasSubstr("loopback"));
}

TEST_F(NetworkCliTest, EveryNetworkCommandHasHelpWithTheServerOption) {
  for (const std::string command : {"stream", "subscribe", "play", "loadtest", "server-models", "health"}) {
    const RunResult result = run({command, "--help"});
    EXPECT_EQ(result.status, 0) << command;
    EXPECT_THAT(result.out, ::testing::StartsWith("Usage: lipsync " + command)) << command;
    EXPECT_THAT(result.out, HasSubstr("--server ADDR")) << command;
  }
}

// The connection group (network.hpp, kConnectionOptions) is declared once and joined into each command.
TEST_F(NetworkCliTest, EveryNetworkCommandTakesTheWholeConnectionGroup) {
  for (const std::string command : {"stream", "speak", "subscribe", "play", "loadtest", "server-models", "health"}) {
    const RunResult help = run({command, "--help"});
    for (const std::string option :
         {"--server ADDR", "--tls", "--ca FILE", "--cert FILE", "--key FILE", "--api-key KEY"}) {
      EXPECT_THAT(help.out, HasSubstr(option)) << command;
    }
    const RunResult flag_with_value = run({command, "--tls=yes"});  // each command's parser knows --tls as a flag
    EXPECT_EQ(flag_with_value.status, 2) << command;
    EXPECT_THAT(flag_with_value.err, HasSubstr("option --tls takes no value, got 'yes'")) << command;
  }
}

// 200 producers in real time, each followed by one subscriber, for 10 s.
TEST_F(NetworkCliTest, Loadtest200RealtimeStreamsDeliverEveryFrameWithoutErrors) {
  const RunResult report = run({"loadtest", "--server", server(), "--producers", "200", "--subscribers-per-session",
                                "1", "--duration", "10", "--phonemes-per-utterance", "20", "--json"});
  ASSERT_EQ(report.status, 0) << report.out << report.err;
  const auto json = nlohmann::json::parse(report.out);
  EXPECT_TRUE(json["every_frame_arrived"].get<bool>());
  EXPECT_THAT(json["errors"], IsEmpty());
  EXPECT_GT(json["utterances"]["complete"].get<int>(), 200);
  EXPECT_EQ(json["frames"]["missing"].get<int>(), 0);
  // In real time a batch leaves per phoneme that releases frames: 20 phonemes give at least
  // the end's batch and at most one per phoneme and the end, each with at least one frame.
  const auto utterances = json["utterances"]["complete"].get<std::uint64_t>();
  const auto batches = json["batches"]["producers"].get<std::uint64_t>();
  EXPECT_GE(batches, utterances);
  EXPECT_LE(batches, utterances * 21);
  EXPECT_LE(batches, json["frames"]["producers"].get<std::uint64_t>());
  EXPECT_EQ(json["batches"]["subscribers"].get<std::uint64_t>(), batches);
  std::cout << report.out;
}

TEST_F(NetworkCliTest, LoadtestFastModeReportsThroughput) {
  const RunResult report = run({"loadtest", "--server", server(), "--producers", "8", "--duration", "2", "--fast"});
  ASSERT_EQ(report.status, 0) << report.out << report.err;
  EXPECT_THAT(report.out, HasSubstr("result: every frame arrived"));
  std::cout << report.out;
}

// The audio mode: live voices of espeak-ng speech at a speaker's pace (Listen), with their
// transcripts sent ahead of the audio and from the audio alone: every stream comes back whole
// (OK, every frame in order to the audio's end) and the latency is measured per frame.
TEST_F(NetworkCliTest, LoadtestListenBringsEveryLiveVoiceBackWhole) {
  for (const bool transcript : {true, false}) {
    SCOPED_TRACE(transcript ? "with transcripts" : "audio alone");
    std::vector<std::string> args = {"loadtest", "--listen",   "--server", server(), "--producers",
                                     "3",        "--duration", "4",        "--json"};
    if (transcript) args.emplace_back("--transcript");
    const RunResult report = run(args);
    ASSERT_EQ(report.status, 0) << report.out << report.err;
    const auto json = nlohmann::json::parse(report.out);
    EXPECT_EQ(json["mode"], "listen");
    EXPECT_EQ(json["streams_whole"].get<int>(), 3);
    EXPECT_THAT(json["errors"], IsEmpty());
    EXPECT_GE(json["frames"].get<int>(), 3 * 4 * 30);  // three streams of 4 s at 30 frames a second
    EXPECT_GT(json["latency_ms"]["p50"].get<double>(), 0);
    std::cout << report.out;
  }
  const RunResult fast = run({"loadtest", "--listen", "--fast", "--server", server()});
  EXPECT_EQ(fast.status, 2);
  EXPECT_THAT(fast.err, HasSubstr("--fast: not an option of --listen"));
  const RunResult without = run({"loadtest", "--transcript", "--server", server()});
  EXPECT_EQ(without.status, 2);
  EXPECT_THAT(without.err, HasSubstr("--transcript: needs --listen"));
}

// The same load through the client library (gRPC's C++ client), which --client grpc keeps
// available (and the default with TLS): both clients must see the same frames.
TEST_F(NetworkCliTest, LoadtestThroughTheGrpcClientLibraryDeliversEveryFrameToo) {
  const RunResult report = run({"loadtest", "--server", server(), "--client", "grpc", "--producers", "20",
                                "--subscribers-per-session", "1", "--duration", "2", "--json"});
  ASSERT_EQ(report.status, 0) << report.out << report.err;
  const auto json = nlohmann::json::parse(report.out);
  EXPECT_EQ(json["client"], "grpc");
  EXPECT_TRUE(json["every_frame_arrived"].get<bool>());
  EXPECT_GT(json["subscriptions"]["complete"].get<int>(), 0);
}

// The generator's own HTTP/2 client carries the API key and the gRPC status of a refusal:
// against a lipsyncd with --api-keys, no key gets every utterance refused (counted by code,
// exit 1), the right key gets every frame, to producers and subscribers.
TEST_F(NetworkCliTest, LoadtestH2ClientSendsTheApiKeyAndCountsRefusalsByStatusCode) {
  testing::write_text(dir_ / "key", "loadtest-key");
  const RunResult hashed = testing::run_program({LIPSYNCD_BINARY, "--hash-key"}, dir_, capture_,
                                                {.stdin_file = dir_ / "key", .path_env = std::nullopt});
  ASSERT_EQ(hashed.status, 0) << hashed.err;
  const std::string hash = hashed.out.substr(0, hashed.out.find('\n'));
  testing::write_text(dir_ / "keys.json",
                      R"({"tenants": {"load": {}}, "keys": [{"tenant": "load", "sha256": ")" + hash + R"("}]})");
  ChildProcess keyed(
      {LIPSYNCD_BINARY, "--listen", "127.0.0.1:0", "--api-keys", (dir_ / "keys.json").string(), "--log-level", "warn"},
      dir_, capture_ / "keyed.out", capture_ / "keyed.err");
  const std::string address = testing::wait_for_listening_address(capture_ / "keyed.out");
  ASSERT_FALSE(address.empty()) << read_text(capture_ / "keyed.err");

  const RunResult refused = run({"loadtest", "--server", address, "--producers", "3", "--duration", "1", "--json"});
  EXPECT_EQ(refused.status, 1) << refused.out << refused.err;
  const auto refused_json = nlohmann::json::parse(refused.out);
  EXPECT_EQ(refused_json["client"], "h2");
  EXPECT_GE(refused_json["errors"].value("UNAUTHENTICATED", 0), 3) << refused.out;
  EXPECT_EQ(refused_json["errors"].size(), 1u) << refused.out;
  EXPECT_EQ(refused_json["utterances"]["complete"].get<int>(), 0);

  const RunResult admitted = run({"loadtest", "--server", address, "--api-key", "loadtest-key", "--producers", "3",
                                  "--subscribers-per-session", "1", "--duration", "1", "--json"});
  ASSERT_EQ(admitted.status, 0) << admitted.out << admitted.err;
  const auto admitted_json = nlohmann::json::parse(admitted.out);
  EXPECT_TRUE(admitted_json["every_frame_arrived"].get<bool>());
  EXPECT_GE(admitted_json["subscriptions"]["complete"].get<int>(), 3);
  keyed.terminate();
  EXPECT_EQ(keyed.wait(), 0);
}

// --timeout and --wait are declared once per command (range and default): the range the help
// states is the one the check enforces, at both ends.
TEST_F(NetworkCliTest, EveryTimeoutAndWaitRefusesExactlyOutsideTheRangeItsHelpStates) {
  const std::regex ranged(R"(--(timeout|wait) S\s+[^\n]*?(\d+) to (\d+) \(default: (\d+)\))");
  int checked = 0;
  for (const std::string command : {"stream", "speak", "subscribe", "play", "server-models", "health"}) {
    std::string help = run({command, "--help"}).out;
    help = std::regex_replace(help, std::regex(R"(\n\s+)"), " ");  // undo the help's line wrapping
    for (std::sregex_iterator match(help.begin(), help.end(), ranged), end; match != end; ++match) {
      const std::string option = "--" + (*match)[1].str();
      const long min = std::stol((*match)[2].str());
      const long max = std::stol((*match)[3].str());
      const long fallback = std::stol((*match)[4].str());
      EXPECT_LE(min, fallback) << command << ' ' << option;
      EXPECT_LE(fallback, max) << command << ' ' << option;
      const std::string range = "(" + std::to_string(min) + " to " + std::to_string(max) + ")";
      for (const long outside : {min - 1, max + 1}) {
        std::vector<std::string> args = {command, option, std::to_string(outside)};
        if (command != "health" && command != "server-models") args.insert(args.begin() + 1, "SESSION");
        const RunResult refused = run(args);
        EXPECT_EQ(refused.status, 2) << command << ' ' << option << ' ' << outside;
        EXPECT_THAT(refused.err, HasSubstr(option + ": '" + std::to_string(outside) + "' is out of range " + range))
            << command;
      }
      ++checked;
    }
  }
  EXPECT_EQ(checked, 7);  // --timeout of all but play, --wait of subscribe and play
}

TEST_F(NetworkCliTest, LoadtestClientChoiceIsChecked) {
  const RunResult unknown = run({"loadtest", "--server", server(), "--client", "http3"});
  EXPECT_EQ(unknown.status, 2);
  EXPECT_THAT(unknown.err, HasSubstr("--client: unknown client 'http3' (choose h2 or grpc)"));
  const RunResult tls = run({"loadtest", "--server", server(), "--client", "h2", "--tls"});
  EXPECT_EQ(tls.status, 2);
  EXPECT_THAT(tls.err, HasSubstr("plaintext HTTP/2 only; with --tls, --ca, --cert or --key use --client grpc"));
}

// A port that answers, but not with HTTP/2 (here: an HTTP/1.1 reply, as a TLS or web server
// would give something else than HTTP/2 settings): exit 1 naming the address and the likely cause.
TEST_F(NetworkCliTest, LoadtestH2ClientAgainstAServerThatIsNotPlaintextHttp2SaysSo) {
  const int listener = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(listener, 0);
  sockaddr_in bound{};
  bound.sin_family = AF_INET;
  bound.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&bound), sizeof bound), 0);
  ASSERT_EQ(::listen(listener, 4), 0);
  socklen_t length = sizeof bound;
  ::getsockname(listener, reinterpret_cast<sockaddr*>(&bound), &length);
  const std::string address = "127.0.0.1:" + std::to_string(ntohs(bound.sin_port));
  std::thread web_server([listener] {
    const int connection = ::accept(listener, nullptr, nullptr);
    if (connection < 0) return;
    const std::string reply = "HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\nConnection: close\r\n\r\n";
    (void)!::write(connection, reply.data(), reply.size());
    ::close(connection);
  });
  const RunResult report = run({"loadtest", "--server", address, "--producers", "1", "--duration", "1"});
  web_server.join();
  ::close(listener);
  EXPECT_EQ(report.status, 1);
  EXPECT_THAT(report.err, HasSubstr("connecting to lipsyncd at " + address));
  EXPECT_THAT(report.err, HasSubstr("did not answer as a plaintext HTTP/2 (gRPC) server"));
}

// --- the server's models ------------------------------------------------------------

TEST_F(NetworkCliTest, ServerModelsListsEveryModelTheServerLoadedForAReader) {
  const RunResult listed = run({"server-models", "--server", server()});
  ASSERT_EQ(listed.status, 0) << listed.err;
  EXPECT_THAT(listed.out, HasSubstr("model default (default)\n"));
  EXPECT_THAT(listed.out, HasSubstr("\nmodel renamed\n"));
  EXPECT_THAT(listed.out, HasSubstr("jaw_rotation"));
  EXPECT_THAT(listed.out, HasSubstr("alt_jaw_rotation"));
  EXPECT_THAT(listed.out, ::testing::ContainsRegex("\n    jaw_rotation +jaw +[-0-9.e]+ +[-0-9.e]+ +[-0-9.e]+  "));
  EXPECT_THAT(listed.out, HasSubstr("ARKit blendshapes: 52"));
  EXPECT_THAT(listed.out, HasSubstr("phone sets: arpabet"));
  EXPECT_THAT(listed.out, ::testing::ContainsRegex("phonemes \\([0-9]+\\): aa "));
}

TEST_F(NetworkCliTest, ServerModelsJsonDescribesEachModelForScripts) {
  const RunResult listed = run({"server-models", "--server", server(), "--json"});
  ASSERT_EQ(listed.status, 0) << listed.err;
  const auto list = nlohmann::json::parse(listed.out);
  ASSERT_EQ(list["models"].size(), 2u);
  EXPECT_EQ(list["models"][0]["name"], "default");
  EXPECT_TRUE(list["models"][0]["default"].get<bool>());
  EXPECT_FALSE(list["models"][1]["default"].get<bool>());

  const RunResult one = run({"server-models", "renamed", "--server", server(), "--json"});
  ASSERT_EQ(one.status, 0) << one.err;
  const auto model = nlohmann::json::parse(one.out);
  EXPECT_EQ(model, list["models"][1]);
  EXPECT_EQ(model["name"], "renamed");
  ASSERT_EQ(model["channels"].size(), 16u);
  const auto& jaw = model["channels"][13];
  EXPECT_EQ(jaw["name"], "alt_jaw_rotation");
  EXPECT_EQ(jaw["kind"], "jaw");
  EXPECT_LT(jaw["min"].get<double>(), jaw["max"].get<double>());
  EXPECT_TRUE(jaw.contains("rest"));
  EXPECT_FALSE(jaw["description"].get<std::string>().empty());
  EXPECT_EQ(model["arkit_names"].size(), 52u);
  EXPECT_THAT(model["phone_sets"], ::testing::Contains("arpabet"));
  EXPECT_THAT(model["phonemes"], ::testing::Contains("sil"));
}

TEST_F(NetworkCliTest, ServerModelsOfAnUnknownNameExits1WithTheServersNotFound) {
  const RunResult result = run({"server-models", "no-such-model", "--server", server()});
  EXPECT_EQ(result.status, 1);
  EXPECT_THAT(result.err, HasSubstr("NOT_FOUND: no model named 'no-such-model'"));
  EXPECT_THAT(result.out, IsEmpty());
}

TEST_F(NetworkCliTest, ServerModelsWithoutAServerExits1SayingItCannotBeReached) {
  const std::string nowhere = "127.0.0.1:" + std::to_string(unused_port());
  const RunResult result = run({"server-models", "--server", nowhere, "--timeout", "1"});
  EXPECT_EQ(result.status, 1);
  EXPECT_THAT(result.err, HasSubstr("connecting to lipsyncd at " + nowhere + " failed: UNAVAILABLE"));
  EXPECT_THAT(result.err, HasSubstr("is lipsyncd running there?"));
}

TEST_F(NetworkCliTest, HealthPrintsServingAndExits0AndExits1WhenNoServerAnswers) {
  const RunResult serving = run({"health", "--server", server()});
  EXPECT_EQ(serving.status, 0) << serving.err;
  EXPECT_EQ(serving.out, "SERVING\n");
  const std::string nowhere = "127.0.0.1:" + std::to_string(unused_port());
  const RunResult down = run({"health", "--server", nowhere, "--timeout", "1"});
  EXPECT_EQ(down.status, 1);
  EXPECT_THAT(down.err, HasSubstr("lipsyncd at " + nowhere + " did not answer: DEADLINE_EXCEEDED"));
  EXPECT_THAT(down.out, IsEmpty());
}

TEST_F(NetworkCliTest, ServerModelsUsageErrorsExit2NamingTheMistake) {
  const RunResult two = run({"server-models", "a", "b", "--server", server()});
  EXPECT_EQ(two.status, 2);
  EXPECT_THAT(two.err, HasSubstr("at most one model NAME"));
  const RunResult timeout = run({"server-models", "--timeout", "0", "--server", server()});
  EXPECT_EQ(timeout.status, 2);
  EXPECT_THAT(timeout.err, HasSubstr("--timeout"));
  const RunResult help = run({"--help"});
  EXPECT_THAT(help.out, HasSubstr("\n  server-models "));
  EXPECT_THAT(help.out, HasSubstr("'model dump' prints a model file on this machine"));
}

// --- frames named after the server's model ------------------------------------------------

TEST_F(NetworkCliTest, StreamWritesTheChannelNamesOfTheServersModel) {
  for (const std::string format : {"json", "csv", "arkit-csv"}) {
    const RunResult rendered = run({"render", fixture("hello.json"), "--format", format, "-o", "render.out"});
    ASSERT_EQ(rendered.status, 0) << rendered.err;
    const RunResult streamed = run({"stream", fixture("hello.json"), "--fast", "--server-model", "renamed", "--server",
                                    server(), "--format", format, "-o", "stream.out"});
    ASSERT_EQ(streamed.status, 0) << streamed.err;
    // arkit-csv has no channel columns: the ARKit weights are the server's, equal to the built-in ones.
    const std::string expected =
        format == "arkit-csv" ? output("render.out") : as_renamed(output("render.out"), format);
    EXPECT_EQ(output("stream.out"), expected) << format;
  }
}

TEST_F(NetworkCliTest, SubscribeWritesTheChannelNamesOfTheSessionsModel) {
  ASSERT_EQ(run({"render", fixture("hello.json"), "-o", "render.json"}).status, 0);
  auto producer = start({"stream", fixture("hello.json"), "--server-model", "renamed", "--session", "renamed-session",
                         "--format", "csv", "--server", server(), "-o", "stream.csv"},
                        "producer");
  const RunResult subscribed =
      run({"subscribe", "renamed-session", "--wait", "5", "--server", server(), "-o", "subscribe.json"});
  ASSERT_EQ(producer->wait(), 0) << read_text(capture_ / "producer.err");
  ASSERT_EQ(subscribed.status, 0) << subscribed.err;
  // The producer asked for channels only (csv): the subscriber writes no ARKit weights
  // rather than the built-in model's retargeting of channels it does not have.
  const auto json = nlohmann::json::parse(output("subscribe.json"));
  const auto expected = nlohmann::json::parse(as_renamed(output("render.json"), "json"));
  EXPECT_EQ(json["model"], "renamed");
  EXPECT_EQ(json["channels"], expected["channels"]);
  EXPECT_THAT(json["arkit_names"], IsEmpty());
  ASSERT_EQ(json["frames"].size(), expected["frames"].size());
  for (std::size_t f = 0; f < json["frames"].size(); ++f) {
    EXPECT_EQ(json["frames"][f]["values"], expected["frames"][f]["values"]) << "frame " << f;
  }
  const RunResult arkit = run({"subscribe", "renamed-session", "--server", server(), "--format", "arkit-csv"});
  EXPECT_EQ(arkit.status, 1);
  EXPECT_THAT(arkit.err, HasSubstr("no ARKit weights and its model 'renamed' is not the built-in one"));
}

TEST_F(NetworkCliTest, StreamWithAnUnknownServerModelExits1NamingIt) {
  const RunResult result = run({"stream", fixture("hello.json"), "--fast", "--server-model", "no-such-model",
                                "--server", server(), "-o", "out.json"});
  EXPECT_EQ(result.status, 1);
  EXPECT_THAT(result.err, HasSubstr("INVALID_ARGUMENT: settings.model: unknown model 'no-such-model'"));
  EXPECT_FALSE(fs::exists(dir_ / "out.json"));
}

// --- the load test with the mesh output ----------------------------------------------------------

TEST_F(NetworkCliTest, LoadtestWithAMeshShareReportsMeshFramesApartWithoutErrors) {
  const RunResult report =
      run({"loadtest", "--server", server(), "--producers", "4", "--mesh-share", "0.5", "--mesh-subdivision", "0",
           "--mesh-solve", "fast", "--fast", "--duration", "2", "--json"});
  ASSERT_EQ(report.status, 0) << report.out << report.err;
  const auto json = nlohmann::json::parse(report.out);
  EXPECT_EQ(json["mesh"]["solve"], "fast");
  EXPECT_TRUE(json["every_frame_arrived"].get<bool>());
  EXPECT_THAT(json["errors"], IsEmpty());
  const auto& mesh = json["by_output"]["mesh"];
  const auto& no_mesh = json["by_output"]["no_mesh"];
  EXPECT_EQ(mesh["producers"].get<int>(), 2);
  EXPECT_EQ(no_mesh["producers"].get<int>(), 2);
  EXPECT_GT(mesh["frames"]["producers"].get<int>(), 0);
  EXPECT_GT(no_mesh["frames"]["producers"].get<int>(), 0);
  EXPECT_EQ(mesh["frames"]["without_positions"].get<int>(), 0);
  EXPECT_EQ(mesh["utterances"]["complete"], mesh["utterances"]["started"]);
  EXPECT_GT(mesh["latency_ms"]["producers"]["max"].get<double>(), 0.0);
  EXPECT_EQ(json["frames"]["producers"].get<int>(),
            mesh["frames"]["producers"].get<int>() + no_mesh["frames"]["producers"].get<int>());
}

TEST_F(NetworkCliTest, LoadtestMeshOptionsOutOfRangeAreUsageErrors) {
  const RunResult share = run({"loadtest", "--server", server(), "--mesh-share", "1.5"});
  EXPECT_EQ(share.status, 2);
  EXPECT_THAT(share.err, HasSubstr("--mesh-share: '1.5' is out of range"));
  const RunResult encoding = run({"loadtest", "--server", server(), "--mesh-share", "1", "--mesh-encoding", "f16"});
  EXPECT_EQ(encoding.status, 2);
  EXPECT_THAT(encoding.err, HasSubstr("--mesh-encoding: unknown encoding 'f16'"));
  const RunResult level = run({"loadtest", "--server", server(), "--mesh-share", "1", "--mesh-subdivision", "3"});
  EXPECT_EQ(level.status, 2);
  EXPECT_THAT(level.err, HasSubstr("--mesh-subdivision"));
  const RunResult solve = run({"loadtest", "--server", server(), "--mesh-share", "1", "--mesh-solve", "quick"});
  EXPECT_EQ(solve.status, 2);
  EXPECT_THAT(solve.err, HasSubstr("--mesh-solve: unknown solve 'quick'"));
  const RunResult alone = run({"loadtest", "--server", server(), "--mesh-solve", "fast"});
  EXPECT_EQ(alone.status, 2);
  EXPECT_THAT(alone.err, HasSubstr("need --mesh-share above 0"));
}

}  // namespace
}  // namespace lipsync
