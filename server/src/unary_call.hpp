// Unary calls (Render, ListModels, GetModel) on the callback API: the work runs
// in the method (or on a face thread), nothing escapes it (an exception becomes
// INTERNAL), a failure is logged with the peer, and the default reactor
// finishes the call.
#pragma once

#include <exception>
#include <utility>

#include <grpcpp/grpcpp.h>
#include <spdlog/spdlog.h>

#include "call_log.hpp"

namespace lipsync::server {

/// The status `function` returns, INTERNAL if it throws; logged unless OK.
template <class Function>
grpc::Status run_unary(grpc::CallbackServerContext* context, const char* method, Function&& function) {
  grpc::Status status;
  try {
    status = function();
  } catch (const std::exception& error) {
    status = grpc::Status(grpc::StatusCode::INTERNAL, error.what());
  }
  if (!status.ok()) spdlog::info("{} peer={} status={}", method, context->peer(), status_name(status));
  return status;
}

/// Runs `function` now and finishes the call with its status.
template <class Function>
grpc::ServerUnaryReactor* unary(grpc::CallbackServerContext* context, const char* method, Function&& function) {
  auto* reactor = context->DefaultReactor();
  reactor->Finish(run_unary(context, method, std::forward<Function>(function)));
  return reactor;
}

}  // namespace lipsync::server
