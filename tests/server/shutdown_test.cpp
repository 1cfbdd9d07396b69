// Shutdown, as docs/server.md ("Shutdown") promises it, against the lipsyncd
// binary (SIGTERM) and an in-process server: the process ends within 100 ms of
// the client's receipt of the last call's status, also after a mesh Render with
// the CPU loaded (the face threads run at SCHED_IDLE, and a process cannot end
// before its idlest thread has had CPU time to die); a mesh Render running at
// SIGTERM gets its response (the call counts until gRPC's OnDone, not until
// Finish); streams and subscribers still open at the drain deadline get ABORTED,
// not gRPC's UNAVAILABLE.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <thread>
#include <vector>

#include "../support/sanitizers.hpp"
#include "../support/server_harness.hpp"

namespace lipsync::server {
namespace {

using namespace harness;
using namespace std::chrono_literals;

v1::RenderRequest mesh_render_request(std::size_t phonemes) {
  v1::RenderRequest request;
  request.mutable_settings()->mutable_outputs()->mutable_mesh()->set_enabled(true);
  request.mutable_settings()->mutable_outputs()->mutable_mesh()->set_subdivision(0);
  for (const auto& interval : utterance(phonemes, 11)) *request.add_phonemes() = to_proto(interval);
  return request;
}

/// Processes that spin on the CPU until destroyed: one more than there are cores,
/// so that no CPU time is ever left over for SCHED_IDLE threads.
class BusyProcesses {
 public:
  BusyProcesses() {
    const unsigned count = std::max(2u, std::thread::hardware_concurrency()) + 1;
    for (unsigned i = 0; i < count; ++i) {
      const pid_t pid = fork();
      if (pid == 0) {
        volatile unsigned long spin = 0;
        while (true) spin = spin + 1;
      }
      pids_.push_back(pid);
    }
    std::this_thread::sleep_for(200ms);  // all of them running
  }
  ~BusyProcesses() {
    for (const pid_t pid : pids_) kill(pid, SIGKILL);
    for (const pid_t pid : pids_) waitpid(pid, nullptr, 0);
  }

 private:
  std::vector<pid_t> pids_;
};

struct Exit {
  std::optional<int> code;  ///< nullopt: killed past the limit
  std::chrono::steady_clock::time_point at;
};

/// When waitpid saw the child end (blocking, not polled), and its exit code; SIGKILL past `limit`.
Exit wait_for_exit(Child& child, std::chrono::seconds limit) {
  auto exited = std::async(std::launch::async, [&child] {
    const int code = child.wait();
    return Exit{code, std::chrono::steady_clock::now()};
  });
  if (exited.wait_for(limit) == std::future_status::timeout) {
    kill(child.pid, SIGKILL);
    return Exit{std::nullopt, exited.get().at};
  }
  return exited.get();
}

/// A lipsyncd whose face threads have worked (one mesh Render), and a client connected to it.
struct RenderedServer {
  explicit RenderedServer(const std::vector<std::string>& flags) : child(spawn(flags)) {
    stub = v1::LipSync::NewStub(connect(listening_address(child)));
    grpc::ClientContext context;
    set_deadline(context);
    v1::RenderResponse response;
    const grpc::Status status = stub->Render(&context, mesh_render_request(6), &response);
    EXPECT_TRUE(status.ok()) << status.error_message();
    EXPECT_GT(response.frames().mesh_positions_size(), 0);
  }
  Child child;
  std::unique_ptr<v1::LipSync::Stub> stub;
};

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

// The bug: the idle face threads, once they had worked, kept the process alive for 10 s and more.
// Measured as a user sees it: from the client's receipt of the last call's status (a stream running
// at SIGTERM) to the exit, five times with the CPU loaded. That time is lipsyncd's (the 50 ms
// connection grace, the drain) plus the kernel's: every thread must get a time slice to die, which
// with three busy processes on the 2-core development machine took 25 to 60 ms, and more the more
// other work loads it (docs/server.md, "Shutdown"). So each run also times the kernel's part alone,
// in the same conditions: SIGKILL to the end of the same lipsyncd (face threads at normal priority,
// or SIGKILL too would wait for them). The promise: the median exit, less the median SIGKILL, under
// 100 ms; and no run over 1 s (the old hang took seconds). Under ThreadSanitizer only the second
// holds: there the exit runs every destructor and thread exit instrumented, which SIGKILL skips, and
// on a busy machine the medians' difference was 116-270 ms, where the product build stays under
// 100 ms.
TEST(Shutdown, SigtermAfterAMeshRenderExitsWithin100MsOfTheLastStatusBeyondTheKernelsOwnTimeWithTheCpuLoaded) {
  std::vector<double> exit_ms, kill_ms;
  for (int run = 0; run < 5; ++run) {
    RenderedServer drained({"--listen", "127.0.0.1:0", "--log-level", "warn"});
    RenderedServer killed({"--listen", "127.0.0.1:0", "--log-level", "warn", "--face-priority", "normal"});
    BusyProcesses busy;
    Producer running(*drained.stub, {});
    running.write(chunked(utterance(10, 3), 10)[0]);
    ASSERT_EQ(kill(drained.child.pid, SIGTERM), 0);
    std::this_thread::sleep_for(100ms);  // the drain has begun and waits for the stream
    running.write(end_request());
    const Received last = running.finish();
    const auto last_status = std::chrono::steady_clock::now();
    ASSERT_TRUE(last.status.ok()) << last.status.error_message();
    const Exit exit = wait_for_exit(drained.child, 20s);
    EXPECT_EQ(exit.code, std::optional<int>(0));
    exit_ms.push_back(std::chrono::duration<double, std::milli>(exit.at - last_status).count());

    const auto signalled = std::chrono::steady_clock::now();
    ASSERT_EQ(kill(killed.child.pid, SIGKILL), 0);
    kill_ms.push_back(
        std::chrono::duration<double, std::milli>(wait_for_exit(killed.child, 20s).at - signalled).count());
    std::printf("%u busy processes: last status to exit %.0f ms, SIGKILL to exit %.0f ms\n",
                std::max(2u, std::thread::hardware_concurrency()) + 1, exit_ms.back(), kill_ms.back());
  }
  if (!lipsync::testing::kUnderThreadSanitizer) {
    EXPECT_LT(median(exit_ms) - median(kill_ms), 100.0)
        << "exit " << ::testing::PrintToString(exit_ms) << ", SIGKILL " << ::testing::PrintToString(kill_ms);
  }
  EXPECT_LT(*std::max_element(exit_ms.begin(), exit_ms.end()), 1000.0) << ::testing::PrintToString(exit_ms);
}

TEST(Shutdown, AMeshRenderRunningAtSigtermGetsItsResponse) {
  Child child = spawn(
      {"--listen", "127.0.0.1:0", "--drain-deadline-ms", "60000", "--log-level", "warn", "--face-priority", "normal"});
  auto channel = connect(listening_address(child));
  ASSERT_TRUE(channel->WaitForConnected(std::chrono::system_clock::now() + 10s));
  auto stub = v1::LipSync::NewStub(channel);
  // About 1.5 s of solver work alone on a quiet core (a Render of 300 phonemes took 0.25 s there
  // and ended before the SIGTERM), more under load.
  const v1::RenderRequest request = mesh_render_request(1800);
  auto rendered = std::async(std::launch::async, [&] {
    grpc::ClientContext context;
    set_deadline(context);
    v1::RenderResponse response;
    const grpc::Status status = stub->Render(&context, request, &response);
    return std::make_pair(status, response.frames().t_us_size());
  });
  std::this_thread::sleep_for(300ms);
  if (rendered.wait_for(0s) != std::future_status::timeout) {
    const auto [status, frames] = rendered.get();
    FAIL() << "the Render ended before SIGTERM, status " << status.error_code() << " '" << status.error_message()
           << "', " << frames << " frames";
  }
  ASSERT_EQ(kill(child.pid, SIGTERM), 0);
  const auto [status, frames] = rendered.get();
  EXPECT_TRUE(status.ok()) << status.error_message();
  EXPECT_GT(frames, 0);
  EXPECT_EQ(child.wait_for(20s), std::optional<int>(0));
}

TEST(Shutdown, StreamsAndSubscribersOpenAtTheDrainDeadlineGetAborted) {
  ServerConfig config;
  config.listen = "127.0.0.1:0";
  config.log_level = "off";
  Server server(config);
  auto stub = v1::LipSync::NewStub(connect(server.address()));
  Producer producer(*stub, session_settings("drained"));
  producer.write(chunked(utterance(20, 2), 20)[0]);
  Subscriber subscriber(*stub, "drained", v1::SubscribeRequest::START_FROM_BEGINNING);
  ASSERT_TRUE(subscriber.attached());
  Producer private_stream(*stub, {});
  std::thread drain([&] { server.shutdown(200ms); });
  // The producers keep their request side open: closing it after the subscriber's abort could
  // reach the server before the drain has aborted them too (seen under TSan).
  const Received followed = subscriber.finish();
  const Received produced = producer.finish_when_the_server_ends_it();
  const Received unnamed = private_stream.finish_when_the_server_ends_it();
  drain.join();
  for (const Received* received : {&followed, &produced, &unnamed}) {
    EXPECT_EQ(received->status.error_code(), grpc::StatusCode::ABORTED) << received->status.error_message();
  }
  EXPECT_NE(produced.status.error_message().find("--drain-deadline-ms=200"), std::string::npos)
      << produced.status.error_message();
}

}  // namespace
}  // namespace lipsync::server
