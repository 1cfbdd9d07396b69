// ListModels and GetModel: what the server's models are (channels with their
// ranges and rest values, ARKit names, phonemes, phone sets), from the catalog.
#include "lipsync/excerpt.hpp"
#include "rpc/service.hpp"
#include "rpc/unary_call.hpp"

namespace lipsync::server {
namespace {

void describe(const ModelEntry& entry, v1::ModelInfo& info) {
  info.set_name(entry.name);
  for (const ChannelSpec& spec : entry.model->channels()) {
    auto& channel = *info.add_channels();
    channel.set_name(spec.name);
    channel.set_kind(spec.kind);
    channel.set_min(spec.min);
    channel.set_max(spec.max);
    channel.set_rest(spec.rest);
    channel.set_description(spec.description);
  }
  for (const auto name : kArkitNames) info.add_arkit_names(std::string(name));
  for (const PhonemeSpec& phoneme : entry.model->phonemes()) info.add_phonemes(phoneme.name);
  for (const PhoneSet& set : entry.phone_sets) info.add_phone_sets(set.name());
  info.set_is_default(entry.is_default);
}

}  // namespace

UnaryCall* LipSyncService::start_model_query(const char* method, grpc::CallbackServerContext& context) {
  handoff_acquire(this);     // the service as built before the server started (tsan_handoff.hpp)
  admission_.count_query();  // the drain waits for the call's end, its access line and metrics included
  return new UnaryCall(*this, method, context, [this](const grpc::Status&) { admission_.release_query(); });
}

grpc::Status LipSyncService::authenticate_model_query(const char* method, grpc::CallbackServerContext& context,
                                                      UnaryCall& call) {
  Caller caller;
  if (auto status = tenants_.authenticate(context, method, caller); !status.ok()) return status;
  call.set_tenant(caller.tenant());
  return grpc::Status::OK;
}

grpc::ServerUnaryReactor* LipSyncService::ListModels(grpc::CallbackServerContext* context, const v1::ListModelsRequest*,
                                                     v1::ListModelsResponse* response) {
  auto* call = start_model_query("ListModels", *context);
  call->run([&] {
    if (auto status = authenticate_model_query("ListModels", *context, *call); !status.ok()) return status;
    for (const auto& entry : catalog_.entries()) describe(*entry, *response->add_models());
    return grpc::Status::OK;
  });
  return call;
}

grpc::ServerUnaryReactor* LipSyncService::GetModel(grpc::CallbackServerContext* context,
                                                   const v1::GetModelRequest* request, v1::ModelInfo* response) {
  auto* call = start_model_query("GetModel", *context);
  call->run([&] {
    if (auto status = authenticate_model_query("GetModel", *context, *call); !status.ok()) return status;
    const ModelEntry* entry = catalog_.find(request->name());
    if (!entry) {
      return grpc::Status(grpc::StatusCode::NOT_FOUND,
                          "no model named " + excerpt(request->name()) + " (known: " + catalog_.names() + ")");
    }
    describe(*entry, *response);
    return grpc::Status::OK;
  });
  return call;
}

}  // namespace lipsync::server
