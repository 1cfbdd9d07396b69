// Unary calls (Render, ListModels, GetModel) on the callback API: the work runs
// in the method (or on a face thread), nothing escapes it (an exception becomes
// INTERNAL), and a reactor of our own finishes the call. The call counts as
// running until gRPC says it is done (OnDone: the response has left, or the call
// was cancelled), not until Finish is called: a drain that waits for the calls
// in progress then also waits for a response still being sent. OnDone writes the
// call's access line with the status the client received.
#pragma once

#include <grpcpp/grpcpp.h>

#include <atomic>
#include <exception>
#include <functional>
#include <utility>

#include "call_log.hpp"
#include "lipsync/tsan_handoff.hpp"
#include "rpc/service.hpp"

namespace lipsync::server {

/// The status `function` returns, INTERNAL if it throws.
template <class Function>
grpc::Status run_guarded(Function&& function) {
  try {
    return function();
  } catch (const std::exception& error) {
    return grpc::Status(grpc::StatusCode::INTERNAL, error.what());
  }
}

class UnaryCall final : public HandoffReactor<grpc::ServerUnaryReactor> {
 public:
  /// `on_done` runs once the call is done (after the access line), on a gRPC thread.
  UnaryCall(LipSyncService& service, const char* method, grpc::CallbackServerContext& context,
            std::function<void(const grpc::Status&)> on_done = {})
      : service_(service), log_(method, context, &service.metrics()), on_done_(std::move(on_done)) {}

  /// Runs `function` (may be called on any thread) and finishes the call with its status.
  template <class Function>
  void run(Function&& function) {
    status_ = run_guarded(std::forward<Function>(function));
    Finish(status_);
  }

  /// The caller's tenant, once authenticated (call_log.hpp).
  void set_tenant(std::string tenant) { log_.set_tenant(std::move(tenant)); }

  void OnCancel() override {
    const HandoffScope handoff = reaction();
    cancelled_ = true;
  }
  void OnDone() override {
    last_reaction();
    const grpc::Status received = cancelled_ ? cancelled_status() : status_;
    log_.ended(received);
    if (on_done_) on_done_(received);
    service_.call_ended();
    delete this;
  }

 private:
  LipSyncService& service_;
  CallLog log_;
  std::function<void(const grpc::Status&)> on_done_;
  grpc::Status status_;
  std::atomic<bool> cancelled_ = false;
};

/// Runs `function` now and finishes the call with its status.
template <class Function>
grpc::ServerUnaryReactor* unary(LipSyncService& service, grpc::CallbackServerContext* context, const char* method,
                                Function&& function) {
  auto* call = new UnaryCall(service, method, *context);
  call->run(std::forward<Function>(function));
  return call;
}

}  // namespace lipsync::server
