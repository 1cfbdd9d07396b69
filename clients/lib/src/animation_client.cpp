// AnimationClient, the client of lipsync.v1.LipSync (see animation_client.hpp): the channel,
// and the blocking calls (Render, Animate and Subscribe to the end, Speak, ListModels,
// GetModel). The streams' reactors are in stream_calls.cpp, the tracks received in
// received_track.cpp, TLS and API keys in credentials.cpp, CallError in call_error.cpp.
#include "lipsync/client/animation_client.hpp"

#include <utility>

#include "call_context.hpp"

namespace lipsync::client {

using detail::add_session_metadata;
using detail::deadline_after;
using detail::protocol_error;
using detail::throw_unless_ok;

AnimationClient::AnimationClient(std::string address, ClientOptions options)
    : address_(std::move(address)), options_(std::move(options)) {
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(256 * 1024 * 1024);
  // Each client gets its own connection, so that a load test can spread its streams.
  arguments.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  channel_ = grpc::CreateCustomChannel(address_, channel_credentials(options_.tls), arguments);
  stub_ = v1::LipSync::NewStub(channel_);
}

void AnimationClient::wait_connected() const {
  if (!channel_->WaitForConnected(deadline_after(options_.connect_timeout))) {
    throw CallError("connecting to lipsyncd at " + address_, grpc::StatusCode::UNAVAILABLE,
                    "no answer within " + std::to_string(options_.connect_timeout.count()) + " ms " +
                        unreachable_hint(options_.tls));
  }
}

ReceivedTrack AnimationClient::render(const v1::AnimationSettings& settings,
                                      std::span<const v1::Phoneme> phonemes) const {
  v1::RenderRequest request;
  *request.mutable_settings() = settings;
  request.mutable_phonemes()->Reserve(static_cast<int>(phonemes.size()));
  for (const v1::Phoneme& phoneme : phonemes) *request.add_phonemes() = phoneme;
  grpc::ClientContext context;
  context.set_deadline(deadline_after(options_.unary_timeout));
  add_api_key(context, options_.api_key);
  v1::RenderResponse response;
  throw_unless_ok(stub_->Render(&context, request, &response), "Render on " + address_);
  ReceivedTrack received;
  v1::TrackMessage message;
  *message.mutable_header() = response.header();
  received.add(message);
  received.add_frames(response.frames());
  received.summary = response.summary();
  return received;
}

ReceivedTrack AnimationClient::animate(const v1::AnimationSettings& settings,
                                       std::span<const std::vector<v1::Phoneme>> chunks,
                                       const MessageHandler& handler) const {
  ReceivedTrack received;
  auto call = start_animate(settings, [&](const v1::TrackMessage& message) {
    received.add(message);
    if (handler) handler(message);
  });
  for (const std::vector<v1::Phoneme>& chunk : chunks) {
    if (!call->send(chunk)) break;
  }
  call->end();
  throw_unless_ok(call->wait(), "Animate on " + address_);
  return received;
}

ReceivedTrack AnimationClient::subscribe(const std::string& session, v1::SubscribeRequest::Start start,
                                         const MessageHandler& handler) const {
  ReceivedTrack received;
  auto call = start_subscribe(session, start, [&](const v1::TrackMessage& message) {
    received.add(message);
    if (handler) handler(message);
  });
  throw_unless_ok(call->wait(), "Subscribe to session '" + session + "' on " + address_);
  return received;
}

SpokenTrack AnimationClient::speak(const v1::SpeakRequest& request,
                                   const std::function<void(const v1::SpeakResponse&)>& handler) const {
  grpc::ClientContext context;
  context.set_deadline(deadline_after(options_.stream_timeout));
  add_api_key(context, options_.api_key);
  add_session_metadata(context, request.settings().session());
  auto reader = stub_->Speak(&context, request);
  SpokenTrack spoken;
  v1::SpeakResponse message;
  while (reader->Read(&message)) {
    try {
      spoken.add(message);
    } catch (const CallError&) {
      context.TryCancel();
      reader->Finish();
      throw;
    }
    if (handler) handler(message);
  }
  throw_unless_ok(reader->Finish(), "Speak on " + address_);
  if (spoken.samples.size() != spoken.header.sample_count()) {
    throw protocol_error("the Speak stream ended after " + std::to_string(spoken.samples.size()) + " of " +
                         std::to_string(spoken.header.sample_count()) + " samples");
  }
  return spoken;
}

v1::ListModelsResponse AnimationClient::list_models() const {
  grpc::ClientContext context;
  context.set_deadline(deadline_after(options_.unary_timeout));
  add_api_key(context, options_.api_key);
  v1::ListModelsResponse response;
  throw_unless_ok(stub_->ListModels(&context, v1::ListModelsRequest{}, &response), "ListModels on " + address_);
  return response;
}

v1::ModelInfo AnimationClient::get_model(const std::string& name) const {
  grpc::ClientContext context;
  context.set_deadline(deadline_after(options_.unary_timeout));
  add_api_key(context, options_.api_key);
  v1::GetModelRequest request;
  request.set_name(name);
  v1::ModelInfo response;
  throw_unless_ok(stub_->GetModel(&context, request, &response), "GetModel on " + address_);
  return response;
}

}  // namespace lipsync::client
