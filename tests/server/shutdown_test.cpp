// Shutdown, as docs/server.md ("Shutdown") promises it, against the lipsyncd
// binary (SIGTERM) and an in-process server: the process ends as soon as the last
// call has ended, also after a mesh Render with the CPU loaded (the face threads
// run at SCHED_IDLE, and a process cannot end before its idlest thread has had
// CPU time to die); a mesh Render running at SIGTERM gets its response (the call
// counts until gRPC's OnDone, not until Finish); streams and subscribers still
// open at the drain deadline get ABORTED, not gRPC's UNAVAILABLE.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <future>
#include <thread>
#include <vector>

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
        for (volatile unsigned long spin = 0;; spin = spin + 1) {
        }
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

// The bug: the idle face threads, once they had worked, kept the process alive for 10 s and more.
// The bound is functional (seconds before the fix), wide enough for a shared, loaded machine.
TEST(Shutdown, SigtermAfterAMeshRenderExitsWithinASecondAndAHalfWithTheCpuLoaded) {
  for (int run = 0; run < 2; ++run) {
    Child child = spawn({"--listen", "127.0.0.1:0", "--log-level", "warn"});
    auto stub = v1::LipSync::NewStub(connect(listening_address(child)));
    grpc::ClientContext context;
    set_deadline(context);
    v1::RenderResponse response;
    const grpc::Status status = stub->Render(&context, mesh_render_request(6), &response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    ASSERT_GT(response.frames().mesh_positions_size(), 0);
    BusyProcesses busy;
    const auto signalled = std::chrono::steady_clock::now();
    ASSERT_EQ(kill(child.pid, SIGTERM), 0);
    const auto exit_code = child.wait_for(20s);
    const auto exit_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - signalled).count();
    EXPECT_EQ(exit_code, std::optional<int>(0));
    EXPECT_LT(exit_ms, 1500.0) << "run " << run;
    std::printf("SIGTERM to exit after a mesh Render, %u busy processes: %.0f ms\n",
                std::max(2u, std::thread::hardware_concurrency()) + 1, exit_ms);
  }
}

TEST(Shutdown, AMeshRenderRunningAtSigtermGetsItsResponse) {
  Child child = spawn({"--listen", "127.0.0.1:0", "--drain-deadline-ms", "60000", "--log-level", "warn",
                       "--face-priority", "normal"});
  auto channel = connect(listening_address(child));
  ASSERT_TRUE(channel->WaitForConnected(std::chrono::system_clock::now() + 10s));
  auto stub = v1::LipSync::NewStub(channel);
  const v1::RenderRequest request = mesh_render_request(300);  // about a second of solver work
  auto rendered = std::async(std::launch::async, [&] {
    grpc::ClientContext context;
    set_deadline(context);
    v1::RenderResponse response;
    const grpc::Status status = stub->Render(&context, request, &response);
    return std::make_pair(status, response.frames().t_us_size());
  });
  std::this_thread::sleep_for(300ms);
  ASSERT_EQ(rendered.wait_for(0s), std::future_status::timeout) << "the Render ended before SIGTERM";
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
  const Received followed = subscriber.finish();
  const Received produced = producer.finish();
  const Received unnamed = private_stream.finish();
  drain.join();
  for (const Received* received : {&followed, &produced, &unnamed}) {
    EXPECT_EQ(received->status.error_code(), grpc::StatusCode::ABORTED) << received->status.error_message();
  }
  EXPECT_NE(produced.status.error_message().find("--drain-deadline-ms=200"), std::string::npos)
      << produced.status.error_message();
}

}  // namespace
}  // namespace lipsync::server
