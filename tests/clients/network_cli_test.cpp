// End-to-end tests of the network commands: the real lipsyncd (started once
// for the suite on 127.0.0.1:0, its port read from its "listening on" line)
// and the real `lipsync` binary, run in a fresh directory per test.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../support/child_process.hpp"

namespace lipsync {
namespace {

namespace fs = std::filesystem;
using testing::make_temp_dir;
using testing::read_text;
using ::testing::HasSubstr;
using ::testing::IsEmpty;

const fs::path kFixtures = fs::path(LIPSYNC_TEST_DATA_DIR) / "cli";

/// A child process with stdout and stderr going to files.
class Process {
 public:
  Process(const std::string& binary, const std::vector<std::string>& args, const fs::path& cwd,
          const fs::path& out_path, const fs::path& err_path) {
    std::vector<std::string> argv_text = {binary};
    argv_text.insert(argv_text.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (std::string& arg : argv_text) argv.push_back(arg.data());
    argv.push_back(nullptr);
    pid_ = ::fork();
    if (pid_ == 0) {
      const int in = ::open("/dev/null", O_RDONLY);
      const int out = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      const int err = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (in < 0 || out < 0 || err < 0 || ::chdir(cwd.c_str()) != 0) ::_exit(126);
      ::dup2(in, STDIN_FILENO);
      ::dup2(out, STDOUT_FILENO);
      ::dup2(err, STDERR_FILENO);
      ::execv(binary.c_str(), argv.data());
      ::_exit(127);
    }
  }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;
  ~Process() {
    if (pid_ > 0 && !waited_) {
      ::kill(pid_, SIGKILL);
      wait();
    }
  }
  int wait() {
    int status = 0;
    if (pid_ <= 0 || ::waitpid(pid_, &status, 0) != pid_) return -1;
    waited_ = true;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
  void terminate() { ::kill(pid_, SIGTERM); }

 private:
  pid_t pid_ = -1;
  bool waited_ = false;
};

struct RunResult {
  int status = -1;
  std::string out;
  std::string err;
};

class NetworkCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    server_dir_ = new fs::path(make_temp_dir("lipsyncd-test-"));
    server_ = new Process(LIPSYNCD_BINARY,
                          {"--listen", "127.0.0.1:0", "--max-sessions", "5000", "--session-retention-ms", "5000",
                           "--log-level", "warn"},
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

  std::unique_ptr<Process> start(const std::vector<std::string>& args, const std::string& name) {
    return std::make_unique<Process>(LIPSYNC_CLI_BINARY, args, dir_, capture_ / (name + ".out"),
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

  static Process* server_;
  static fs::path* server_dir_;
  static std::string* address_;
  fs::path dir_;
  fs::path capture_;
};

Process* NetworkCliTest::server_ = nullptr;
fs::path* NetworkCliTest::server_dir_ = nullptr;
std::string* NetworkCliTest::address_ = nullptr;

TEST_F(NetworkCliTest, stream_equals_render_byte_for_byte_in_every_format) {
  for (const std::string format : {"json", "csv", "arkit-csv"}) {
    for (const std::string input : {"hello.json", "bump_map.TextGrid"}) {
      const RunResult rendered = run({"render", fixture(input), "--format", format, "-o", "render.out"});
      ASSERT_EQ(rendered.status, 0) << rendered.err;
      const RunResult streamed = run({"stream", fixture(input), "--fast", "--server", server(), "--format", format,
                                      "-o", "stream.out"});
      ASSERT_EQ(streamed.status, 0) << streamed.err;
      EXPECT_EQ(output("stream.out"), output("render.out")) << input << " as " << format;
    }
  }
}

TEST_F(NetworkCliTest, realtime_stream_in_chunks_equals_render) {
  ASSERT_EQ(run({"render", fixture("hello.json"), "-o", "render.json"}).status, 0);
  const RunResult streamed =
      run({"stream", fixture("hello.json"), "--realtime", "--chunk", "3", "--server", server(), "-o", "stream.json"});
  ASSERT_EQ(streamed.status, 0) << streamed.err;
  EXPECT_EQ(output("stream.json"), output("render.json"));
}

TEST_F(NetworkCliTest, subscriber_receives_the_frames_of_a_realtime_stream) {
  ASSERT_EQ(run({"render", fixture("hello.json"), "-o", "render.json"}).status, 0);
  auto producer = start({"stream", fixture("hello.json"), "--session", "subscribe-test", "--server", server(),
                         "-o", "stream.json"},
                        "producer");
  const RunResult subscribed =
      run({"subscribe", "subscribe-test", "--wait", "5", "--server", server(), "-o", "subscribe.json"});
  ASSERT_EQ(producer->wait(), 0) << read_text(capture_ / "producer.err");
  ASSERT_EQ(subscribed.status, 0) << subscribed.err;
  EXPECT_EQ(output("subscribe.json"), output("render.json"));
  EXPECT_EQ(output("stream.json"), output("render.json"));
}

TEST_F(NetworkCliTest, play_prints_a_line_per_update_until_the_session_ends) {
  auto producer = start({"stream", fixture("hello.json"), "--session", "play-test", "--playout-delay", "300",
                         "--server", server(), "-o", "stream.json"},
                        "producer");
  const RunResult played =
      run({"play", "play-test", "--wait", "5", "--no-tty", "--rate", "20", "--server", server()});
  ASSERT_EQ(producer->wait(), 0);
  ASSERT_EQ(played.status, 0) << played.err;
  EXPECT_THAT(played.out, HasSubstr("jaw |"));
  EXPECT_THAT(played.out, HasSubstr("anchored to media clock 'unix'"));
  EXPECT_GT(std::count(played.out.begin(), played.out.end(), '\n'), 10);
}

TEST_F(NetworkCliTest, play_stops_after_the_requested_number_of_updates) {
  auto producer = start({"stream", fixture("hello.json"), "--session", "play-frames-test", "--server", server(),
                         "-o", "stream.json"},
                        "producer");
  const RunResult played = run({"play", "play-frames-test", "--wait", "5", "--no-tty", "--frames", "3",
                                "--rate", "50", "--server", server()});
  ASSERT_EQ(producer->wait(), 0);
  ASSERT_EQ(played.status, 0) << played.err;
  EXPECT_EQ(std::count(played.out.begin(), played.out.end(), '\n'), 4) << played.out;
}

TEST_F(NetworkCliTest, a_rejected_stream_exits_1_with_the_servers_reason_and_leaves_no_file) {
  const RunResult streamed =
      run({"stream", fixture("unknown_label.json"), "--fast", "--server", server(), "-o", "out.json"});
  EXPECT_EQ(streamed.status, 1);
  EXPECT_THAT(streamed.err, HasSubstr("INVALID_ARGUMENT"));
  EXPECT_THAT(fs::directory_iterator(dir_) == fs::directory_iterator(), true);
}

TEST_F(NetworkCliTest, network_failures_exit_1_and_usage_errors_exit_2) {
  const RunResult unknown_session = run({"subscribe", "no-such-session", "--server", server(), "-o", "out.json"});
  EXPECT_EQ(unknown_session.status, 1);
  EXPECT_THAT(unknown_session.err, HasSubstr("NOT_FOUND"));
  EXPECT_FALSE(fs::exists(dir_ / "out.json"));

  EXPECT_EQ(run({"stream", fixture("hello.json"), "--fast", "--realtime"}).status, 2);
  const RunResult remote = run({"loadtest", "--server", "192.0.2.1:50051"});
  EXPECT_EQ(remote.status, 2);
  EXPECT_THAT(remote.err, HasSubstr("loopback"));
}

TEST_F(NetworkCliTest, every_network_command_has_help_with_the_server_option) {
  for (const std::string command : {"stream", "subscribe", "play", "loadtest"}) {
    const RunResult result = run({command, "--help"});
    EXPECT_EQ(result.status, 0) << command;
    EXPECT_THAT(result.out, ::testing::StartsWith("Usage: lipsync " + command)) << command;
    EXPECT_THAT(result.out, HasSubstr("--server ADDR")) << command;
  }
}

// 200 producers in real time, each followed by one subscriber, for 10 s.
TEST_F(NetworkCliTest, loadtest_200_realtime_streams_deliver_every_frame_without_errors) {
  const RunResult report = run({"loadtest", "--server", server(), "--producers", "200", "--subscribers-per-session",
                                "1", "--duration", "10", "--phonemes-per-utterance", "20", "--json"});
  ASSERT_EQ(report.status, 0) << report.out << report.err;
  const auto json = nlohmann::json::parse(report.out);
  EXPECT_TRUE(json["every_frame_arrived"].get<bool>());
  EXPECT_THAT(json["errors"], IsEmpty());
  EXPECT_GT(json["utterances"]["complete"].get<int>(), 200);
  EXPECT_EQ(json["frames"]["missing"].get<int>(), 0);
  std::cout << report.out;
}

TEST_F(NetworkCliTest, loadtest_fast_mode_reports_throughput) {
  const RunResult report = run({"loadtest", "--server", server(), "--producers", "8", "--duration", "2", "--fast"});
  ASSERT_EQ(report.status, 0) << report.out << report.err;
  EXPECT_THAT(report.out, HasSubstr("result: every frame arrived"));
  std::cout << report.out;
}

}  // namespace
}  // namespace lipsync
