// A real lipsyncd for integration tests, and what talks to it: the server
// in-process on 127.0.0.1:0 (LiveServerTest) or the lipsyncd binary as a child
// process (spawn, listening_address; LIPSYNCD_PATH is compiled in), requests
// built from synthetic utterances, synchronous Animate / Subscribe helpers, and
// Producer / Subscriber streams that a test drives step by step. Shared by
// tests/server/server_test.cpp and tests/server/limits_test.cpp.
#pragma once

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "lipsync/server/config.hpp"
#include "lipsync/server/server.hpp"
#include "lipsync/synthetic.hpp"
#include "lipsync/utterance.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"
#include "lipsync/visemes.hpp"

namespace lipsync::server::harness {

inline constexpr auto kCallTimeout = std::chrono::seconds(20);

// --- frames as received -------------------------------------------------------

struct Frames {
  std::vector<std::int64_t> t_us;
  std::vector<int> kinds;
  std::vector<float> values;
  std::vector<float> arkit;
  std::vector<float> viseme_weights;
  std::vector<VisemeEvent> viseme_events;
  std::uint64_t first_frame = 0;

  void append(const v1::FrameBatch& batch) {
    if (t_us.empty()) first_frame = batch.first_frame();
    t_us.insert(t_us.end(), batch.t_us().begin(), batch.t_us().end());
    kinds.insert(kinds.end(), batch.kinds().begin(), batch.kinds().end());
    values.insert(values.end(), batch.values().begin(), batch.values().end());
    arkit.insert(arkit.end(), batch.arkit().begin(), batch.arkit().end());
    viseme_weights.insert(viseme_weights.end(), batch.viseme_weights().begin(), batch.viseme_weights().end());
    for (const auto& event : batch.viseme_events()) viseme_events.push_back({event.viseme(), event.start_us()});
  }
};

inline std::vector<LabeledInterval> utterance(std::size_t phonemes, std::uint64_t seed = 1) {
  return synthesize_utterance({.phonemes = phonemes, .seed = seed});
}

inline v1::Phoneme to_proto(const LabeledInterval& interval) {
  v1::Phoneme phoneme;
  phoneme.set_label(interval.label);
  phoneme.set_start_us(interval.start_us);
  phoneme.set_end_us(interval.end_us);
  return phoneme;
}

// --- requests -----------------------------------------------------------------

inline v1::AnimateRequest settings_request(v1::AnimationSettings settings = {}) {
  v1::AnimateRequest request;
  *request.mutable_settings() = std::move(settings);
  return request;
}

inline v1::AnimateRequest chunk_request(const std::vector<v1::Phoneme>& phonemes) {
  v1::AnimateRequest request;
  for (const auto& p : phonemes) *request.mutable_phonemes()->add_phonemes() = p;
  return request;
}

inline v1::AnimateRequest end_request() {
  v1::AnimateRequest request;
  request.mutable_end();
  return request;
}

inline std::vector<v1::AnimateRequest> chunked(const std::vector<LabeledInterval>& intervals, std::size_t chunk) {
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

inline void take(Received& received, const v1::TrackMessage& message) {
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

inline void set_deadline(grpc::ClientContext& context) {
  context.set_deadline(std::chrono::system_clock::now() + kCallTimeout);
}

inline std::shared_ptr<grpc::Channel> connect(const std::string& address, bool bdp_probe = true) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(-1);
  if (!bdp_probe) args.SetInt(GRPC_ARG_HTTP2_BDP_PROBE, 0);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

/// One Animate call: writes `requests` (then WritesDone), `gap` apart, while another thread reads.
inline Received animate(v1::LipSync::Stub& stub, const std::vector<v1::AnimateRequest>& requests,
                        std::chrono::milliseconds gap = std::chrono::milliseconds(0)) {
  grpc::ClientContext context;
  set_deadline(context);
  auto stream = stub.Animate(&context);
  Received received;
  std::thread reader([&] { read_all(*stream, received); });
  for (const auto& request : requests) {
    if (&request != &requests.front()) std::this_thread::sleep_for(gap);
    if (!stream->Write(request)) break;
  }
  stream->WritesDone();
  reader.join();
  received.status = stream->Finish();
  return received;
}

inline std::vector<v1::AnimateRequest> whole(const v1::AnimationSettings& settings,
                                             const std::vector<LabeledInterval>& intervals, std::size_t chunk) {
  std::vector<v1::AnimateRequest> requests{settings_request(settings)};
  for (auto& request : chunked(intervals, chunk)) requests.push_back(std::move(request));
  requests.push_back(end_request());
  return requests;
}

/// Every message a Subscribe from the beginning of `session` receives, serialised, and how
/// the call ended: what goes over the wire, for byte-for-byte comparisons.
struct SubscribedBytes {
  std::vector<std::string> messages;
  grpc::Status status;
};
inline SubscribedBytes subscribe_bytes(v1::LipSync::Stub& stub, const std::string& session) {
  grpc::ClientContext context;
  set_deadline(context);
  v1::SubscribeRequest request;
  request.set_session(session);
  auto reader = stub.Subscribe(&context, request);
  SubscribedBytes got;
  v1::TrackMessage message;
  while (reader->Read(&message)) got.messages.push_back(message.SerializeAsString());
  got.status = reader->Finish();
  return got;
}

inline Received subscribe_all(v1::LipSync::Stub& stub, const std::string& session,
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
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

// --- the fixture: a real server on 127.0.0.1:0 --------------------------------

class LiveServerTest : public ::testing::Test {
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
    if (server_) server_->shutdown(std::chrono::milliseconds(0));
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
    return finish_when_the_server_ends_it();
  }
  /// Reads until the server ends the call, with the request side left open (a half-close
  /// before `end` would itself end the call, INVALID_ARGUMENT).
  Received finish_when_the_server_ends_it() {
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

inline v1::AnimationSettings session_settings(const std::string& session) {
  v1::AnimationSettings settings;
  settings.set_session(session);
  settings.mutable_media_clock()->set_clock("unix");
  settings.mutable_media_clock()->set_utterance_zero_us(1'700'000'000'000'000);
  return settings;
}

// --- the lipsyncd binary as a child process -------------------------------------

#ifdef LIPSYNCD_PATH
/// A lipsyncd started by `spawn`, its stdout readable line by line. A child still running when
/// this is destroyed (a test that failed before stopping it) is killed and reaped: left running,
/// it would hold the test's stdout open and ctest would wait for it until its timeout.
struct Child {
  pid_t pid = -1;
  FILE* out = nullptr;

  Child() = default;
  Child(pid_t id, FILE* stdout_pipe) : pid(id), out(stdout_pipe) {}
  Child(Child&& other) noexcept
      : pid(std::exchange(other.pid, -1)), out(std::exchange(other.out, nullptr)), reaped(other.reaped) {}
  ~Child() { stop(); }

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
    return exit_code(status);
  }
  /// The exit code if the process ends within `limit`; otherwise it is killed and nullopt returned.
  std::optional<int> wait_for(std::chrono::milliseconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    int status = 0;
    while (waitpid(pid, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        kill(pid, SIGKILL);
        wait();
        return std::nullopt;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return exit_code(status);
  }

 private:
  bool reaped = false;

  void stop() {
    if (pid > 0 && !reaped) {
      kill(pid, SIGKILL);
      wait();
    }
    if (out) fclose(out);
    out = nullptr;
  }
  int exit_code(int status) {
    reaped = true;
    if (out) fclose(out);
    out = nullptr;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  }
};

inline Child spawn(std::vector<std::string> args) {
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

inline std::string listening_address(Child& child) {
  const std::string line = child.line();
  const std::string prefix = "lipsyncd listening on ";
  EXPECT_EQ(line.rfind(prefix, 0), 0u) << line;
  return line.substr(prefix.size(), line.find_last_not_of("\r\n") + 1 - prefix.size());
}
#endif  // LIPSYNCD_PATH

}  // namespace lipsync::server::harness
