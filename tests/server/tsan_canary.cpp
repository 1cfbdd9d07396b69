// The TSan canary: proves that the TSan step still reports a race inside a reaction.
//
// `deploy/sanitize.sh tsan-clang` leaves gRPC's inline code uninstrumented (ignore list),
// states gRPC's hand-offs (HandoffReactor, the preloaded deploy/sanitizers/tsan_edges.cpp), keeps
// libstdc++'s string copies local (deploy/sanitizers/tsan.exports) and suppresses one gRPC assignment
// (deploy/sanitizers/tsan.supp). Each of those removes reports; a clean run means something only if
// a real race in our code would still be reported under all of them. This program plants
// one and the script runs it after the server tests: it must die with a TSan report that
// names the reaction, or the step fails.
//
// The race: a server-streaming reaction of a real callback service on a real port
// (HandoffReactor, as the server's reactors are) increments a counter that a thread of
// ours increments too, with nothing ordering the two. The thread starts before the call
// and is joined only after it, so no edge of gRPC's lies between the two writes whichever
// comes first. Not a test of the suite (no ctest entry, not built by default): under TSan
// it must fail, and without TSan it is a program with a data race.
#include <grpcpp/grpcpp.h>

#include <cstdio>
#include <memory>
#include <thread>

#include "lipsync/tsan_handoff.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace {

int planted_race_counter = 0;  // written by the reaction and by `bystander`, unordered

class CanaryReactor final : public lipsync::HandoffReactor<grpc::ServerWriteReactor<lipsync::v1::TrackMessage>> {
 public:
  CanaryReactor() {
    message_.mutable_header()->set_session("canary");
    StartWrite(&message_);
  }

  void OnWriteDone(bool /*ok*/) override {
    const lipsync::HandoffScope handoff = reaction();
    ++planted_race_counter;  // the planted race
    Finish(grpc::Status::OK);
  }

  void OnDone() override {
    last_reaction();
    delete this;
  }

 private:
  lipsync::v1::TrackMessage message_;
};

class CanaryService final : public lipsync::v1::LipSync::CallbackService {
  grpc::ServerWriteReactor<lipsync::v1::TrackMessage>* Subscribe(
      grpc::CallbackServerContext* /*context*/, const lipsync::v1::SubscribeRequest* /*request*/) override {
    auto* reactor = new CanaryReactor();
    reactor->handed_off();
    return reactor;
  }
};

}  // namespace

int main() {
  CanaryService service;
  int port = 0;
  grpc::ServerBuilder builder;
  builder.AddListeningPort("127.0.0.1:0", grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (server == nullptr || port == 0) {
    std::fprintf(stderr, "tsan_canary: the server did not start\n");
    return 2;
  }

  std::thread bystander([] { ++planted_race_counter; });

  auto channel = grpc::CreateChannel("127.0.0.1:" + std::to_string(port), grpc::InsecureChannelCredentials());
  auto stub = lipsync::v1::LipSync::NewStub(channel);
  grpc::ClientContext context;
  lipsync::v1::SubscribeRequest request;
  request.set_session("canary");
  auto reader = stub->Subscribe(&context, request);
  lipsync::v1::TrackMessage message;
  while (reader->Read(&message)) {
  }
  const grpc::Status status = reader->Finish();
  bystander.join();
  server->Shutdown();
  std::printf("tsan_canary: call ended %d, counter %d: no race reported\n", static_cast<int>(status.error_code()),
              planted_race_counter);
  return 0;
}
