// The client side of lipsync.v1.LipSync (see animation_client.hpp).
//
// Streams use gRPC's callback API. An Animate reactor keeps a queue of
// requests and at most one write in flight; a hold keeps the call open until
// the caller has sent the end marker (or the stream has failed), so that a
// send() from the caller's thread never races the end of the call. gRPC
// operations are started outside the reactor's mutex, because a RemoveHold may
// run OnDone, which takes it.
#include "lipsync/client/animation_client.hpp"

#include <algorithm>
#include <deque>
#include <fstream>
#include <sstream>
#include <utility>

#include "lipsync/grpc_status_name.hpp"
#include "lipsync/tsan_handoff.hpp"

namespace lipsync::client {
namespace {

std::chrono::system_clock::time_point deadline_after(std::chrono::milliseconds timeout) {
  return std::chrono::system_clock::now() + timeout;
}

// The session travels twice: in the body, and as metadata that a balancer can route on (the
// replica holding a session is chosen by hashing it, docs/deploy.md). lipsyncd checks they agree.
void add_session_metadata(grpc::ClientContext& context, const std::string& session) {
  if (!session.empty()) context.AddMetadata(std::string(kSessionMetadataKey), session);
}

std::string read_pem(const std::string& what, const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw CallError("setting up TLS", grpc::StatusCode::INVALID_ARGUMENT,
                    "cannot read the " + what + " '" + path + "'");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void throw_unless_ok(const grpc::Status& status, std::string_view context) {
  if (!status.ok()) throw CallError(context, status.error_code(), status.error_message());
}

CallError protocol_error(const std::string& message) {
  return CallError("reading the server's answer", grpc::StatusCode::INTERNAL, message);
}

}  // namespace

std::string_view status_code_name(grpc::StatusCode code) { return grpc_status_code_name(code); }

CallError::CallError(std::string_view context, grpc::StatusCode code, std::string message)
    : std::runtime_error(std::string(context) + " failed: " + std::string(status_code_name(code)) +
                         (message.empty() ? std::string() : ": " + message)),
      code_(code),
      message_(std::move(message)) {}

FrameKind to_core(v1::FrameKind kind) {
  switch (kind) {
    case v1::FRAME_KIND_CLOSURE_START:
      return FrameKind::closure_start;
    case v1::FRAME_KIND_CLOSURE_END:
      return FrameKind::closure_end;
    case v1::FRAME_KIND_SHORT_SEGMENT:
      return FrameKind::short_segment;
    default:
      return FrameKind::uniform;
  }
}

std::shared_ptr<grpc::ChannelCredentials> channel_credentials(const TlsOptions& tls) {
  if (!tls.on()) return grpc::InsecureChannelCredentials();
  if (tls.cert_file.empty() != tls.key_file.empty()) {
    throw CallError("setting up TLS", grpc::StatusCode::INVALID_ARGUMENT,
                    "a client certificate needs its key and a key its certificate (--cert and --key together)");
  }
  grpc::SslCredentialsOptions options;
  if (!tls.ca_file.empty()) options.pem_root_certs = read_pem("CA file", tls.ca_file);
  if (!tls.cert_file.empty()) {
    options.pem_cert_chain = read_pem("client certificate", tls.cert_file);
    options.pem_private_key = read_pem("client key", tls.key_file);
  }
  return grpc::SslCredentials(options);
}

void add_api_key(grpc::ClientContext& context, const std::string& api_key) {
  if (!api_key.empty()) context.AddMetadata(std::string(kAuthorizationMetadataKey), "Bearer " + api_key);
}

v1::Phoneme to_wire(const LabeledInterval& interval) {
  v1::Phoneme phoneme;
  phoneme.set_label(interval.label);
  phoneme.set_start_us(interval.start_us);
  phoneme.set_end_us(interval.end_us);
  return phoneme;
}

void ReceivedTrack::add(const v1::TrackMessage& message) {
  switch (message.kind_case()) {
    case v1::TrackMessage::kHeader:
      header = message.header();
      track = Track{};
      track.channel_count = static_cast<std::size_t>(header.channels_size());
      track.fps = static_cast<int>(header.fps());
      arkit.clear();
      mesh_positions.clear();
      viseme_weights.clear();
      viseme_events.clear();
      first_frame = 0;
      break;
    case v1::TrackMessage::kFrames:
      add_frames(message.frames());
      break;
    case v1::TrackMessage::kSummary:
      summary = message.summary();
      break;
    default:
      throw protocol_error("a stream message with no content");
  }
}

void ReceivedTrack::add_frames(const v1::FrameBatch& batch) {
  if (header.fps() == 0) throw protocol_error("frames arrived before the track header");
  const auto frames = static_cast<std::size_t>(batch.t_us_size());
  const auto arkit_count = static_cast<std::size_t>(header.arkit_names_size());
  if (track.t_us.empty()) first_frame = batch.first_frame();
  if (batch.first_frame() != first_frame + track.frame_count()) {
    throw protocol_error("frame batch starts at frame " + std::to_string(batch.first_frame()) + ", expected " +
                         std::to_string(first_frame + track.frame_count()));
  }
  const std::size_t mesh_count = header.has_mesh() ? std::size_t{header.mesh().vertex_count()} * 3 : 0;
  const bool int16 = header.has_mesh() && header.mesh().encoding() == v1::MESH_ENCODING_INT16;
  if (int16 && header.mesh().quantisation_offset_m_size() != 3) {
    throw protocol_error("the mesh topology has no int16 quantisation offset");
  }
  if (static_cast<std::size_t>(batch.values_size()) != frames * track.channel_count ||
      static_cast<std::size_t>(batch.arkit_size()) != frames * arkit_count ||
      static_cast<std::size_t>(batch.viseme_weights_size()) !=
          frames * static_cast<std::size_t>(header.viseme_names_size()) ||
      static_cast<std::size_t>(batch.mesh_positions_size()) != (int16 ? 0 : frames * mesh_count) ||
      batch.mesh_positions_int16().size() != (int16 ? frames * mesh_count * 2 : 0) ||
      (batch.kinds_size() != 0 && static_cast<std::size_t>(batch.kinds_size()) != frames)) {
    throw protocol_error("frame batch at frame " + std::to_string(batch.first_frame()) +
                         " has sizes that do not match its " + std::to_string(frames) + " frames");
  }
  for (const v1::VisemeEvent& event : batch.viseme_events()) {
    if (event.viseme() >= static_cast<std::uint32_t>(header.viseme_names_size()) ||
        std::find(batch.t_us().begin(), batch.t_us().end(), event.start_us()) == batch.t_us().end()) {
      throw protocol_error("frame batch at frame " + std::to_string(batch.first_frame()) + " has a viseme event (" +
                           std::to_string(event.viseme()) + " at " + std::to_string(event.start_us()) +
                           " us) that names no viseme or starts at none of its frames");
    }
  }
  for (std::size_t i = 0; i < frames; ++i) {
    const std::int64_t t_us = batch.t_us(static_cast<int>(i));
    if (!track.t_us.empty() && t_us <= track.t_us.back()) {
      throw protocol_error("frame times do not increase at frame " + std::to_string(track.frame_count()));
    }
    track.t_us.push_back(t_us);
    track.kinds.push_back(batch.kinds_size() == 0 ? FrameKind::uniform : to_core(batch.kinds(static_cast<int>(i))));
  }
  track.values.insert(track.values.end(), batch.values().begin(), batch.values().end());
  arkit.insert(arkit.end(), batch.arkit().begin(), batch.arkit().end());
  viseme_weights.insert(viseme_weights.end(), batch.viseme_weights().begin(), batch.viseme_weights().end());
  for (const v1::VisemeEvent& event : batch.viseme_events()) {
    viseme_events.push_back({.viseme = event.viseme(), .start_us = event.start_us()});
  }
  mesh_positions.insert(mesh_positions.end(), batch.mesh_positions().begin(), batch.mesh_positions().end());
  if (int16) {
    const std::string& bytes = batch.mesh_positions_int16();
    const double scale = header.mesh().quantisation_scale_m();
    for (std::size_t i = 0; i + 1 < bytes.size(); i += 2) {
      const auto q = static_cast<std::int16_t>(
          static_cast<std::uint16_t>(static_cast<unsigned>(static_cast<std::uint8_t>(bytes[i])) |
                                     (static_cast<unsigned>(static_cast<std::uint8_t>(bytes[i + 1])) << 8)));
      const double offset = header.mesh().quantisation_offset_m(static_cast<int>((i / 2) % 3));
      mesh_positions.push_back(static_cast<float>(offset + scale * q));
    }
  }
}

namespace detail {

/// Calls `handler` for each message; a throwing handler cancels the call and
/// its message becomes the call's status (INTERNAL).
class HandlerGuard {
 public:
  explicit HandlerGuard(MessageHandler handler) : handler_(std::move(handler)) {}
  bool deliver(const v1::TrackMessage& message, grpc::ClientContext& context) {
    if (!handler_) return true;
    try {
      handler_(message);
      return true;
    } catch (const std::exception& error) {
      error_ = error.what();
    } catch (...) {
      error_ = "the message handler failed";
    }
    context.TryCancel();
    return false;
  }
  grpc::Status adjust(const grpc::Status& status) const {
    if (error_.empty()) return status;
    return grpc::Status(grpc::StatusCode::INTERNAL, error_);
  }

 private:
  MessageHandler handler_;
  std::string error_;
};

/// How a call ends, for the threads that wait on it: OnDone hands the final
/// status to the call's DoneHandler, then records it and wakes the waiters. It
/// is recorded last: a waiter may destroy the reactor as soon as it sees it.
class CallCompletion {
 public:
  explicit CallCompletion(DoneHandler on_done) : on_done_(std::move(on_done)) {}

  void complete(const grpc::Status& status) {
    const DoneHandler on_done = std::move(on_done_);
    if (on_done) on_done(status);
    std::lock_guard lock(mutex_);
    status_ = status;
    done_ = true;
    changed_.notify_all();
  }

  /// The final status, or nothing if the call has not ended within `timeout` (none: wait forever).
  std::optional<grpc::Status> wait_for(std::optional<std::chrono::milliseconds> timeout) {
    std::unique_lock lock(mutex_);
    if (timeout) {
      if (!changed_.wait_for(lock, *timeout, [&] { return done_; })) return std::nullopt;
    } else {
      changed_.wait(lock, [&] { return done_; });
    }
    return status_;
  }

  bool done() const {
    std::lock_guard lock(mutex_);
    return done_;
  }

 private:
  DoneHandler on_done_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool done_ = false;
  grpc::Status status_;
};

class AnimateReactor : public HandoffReactor<grpc::ClientBidiReactor<v1::AnimateRequest, v1::TrackMessage>> {
 public:
  AnimateReactor(v1::LipSync::Stub& stub, const v1::AnimationSettings& settings, MessageHandler handler,
                 DoneHandler on_done, std::chrono::milliseconds timeout, const std::string& api_key)
      : guard_(std::move(handler)), completion_(std::move(on_done)) {
    context_.set_deadline(deadline_after(timeout));
    add_api_key(context_, api_key);
    add_session_metadata(context_, settings.session());
    stub.async()->Animate(&context_, this);
    AddHold();
    hold_held_ = true;
    v1::AnimateRequest first;
    *first.mutable_settings() = settings;
    queue_.push_back(std::move(first));
    act(next_action_locked());
    StartRead(&incoming_);
    StartCall();
  }

  bool send(std::vector<v1::Phoneme> phonemes) {
    v1::AnimateRequest request;
    auto* chunk = request.mutable_phonemes();
    chunk->mutable_phonemes()->Reserve(static_cast<int>(phonemes.size()));
    for (v1::Phoneme& phoneme : phonemes) *chunk->add_phonemes() = std::move(phoneme);
    return enqueue(std::move(request), false);
  }

  bool send_audio(std::string wav_piece) {
    v1::AnimateRequest request;
    *request.mutable_audio()->mutable_wav() = std::move(wav_piece);
    return enqueue(std::move(request), false);
  }

  void end() {
    v1::AnimateRequest request;
    request.mutable_end();
    enqueue(std::move(request), true);
  }

  void cancel() {
    context_.TryCancel();
    Action action = Action::none;
    {
      std::lock_guard lock(mutex_);
      aborted_ = true;
      if (!writing_) action = next_action_locked();
    }
    act(action);
  }

  grpc::Status wait() { return *completion_.wait_for(std::nullopt); }
  bool done() const { return completion_.done(); }

  void OnReadDone(bool ok) override {
    const HandoffScope handoff = reaction();
    if (ok && guard_.deliver(incoming_, context_)) {
      StartRead(&incoming_);
      return;
    }
    Action action = Action::none;
    {
      std::lock_guard lock(mutex_);
      aborted_ = true;
      if (!writing_) action = next_action_locked();
    }
    act(action);
  }

  void OnWriteDone(bool ok) override {
    const HandoffScope handoff = reaction();
    Action action;
    {
      std::lock_guard lock(mutex_);
      writing_ = false;
      if (!ok) aborted_ = true;
      action = next_action_locked();
    }
    act(action);
  }

  // Last: a waiter may destroy this reactor as soon as the call is complete.
  void OnDone(const grpc::Status& status) override {
    last_reaction();
    completion_.complete(guard_.adjust(status));
  }

 private:
  enum class Action { none, write, close_and_release, release };

  bool enqueue(v1::AnimateRequest request, bool is_end) {
    Action action = Action::none;
    {
      std::lock_guard lock(mutex_);
      if (aborted_ || end_queued_) return false;
      queue_.push_back(std::move(request));
      end_queued_ = is_end;
      if (!writing_) action = next_action_locked();
    }
    act(action);
    return true;
  }

  Action next_action_locked() {
    if (aborted_) {
      queue_.clear();
      if (!hold_held_) return Action::none;
      hold_held_ = false;
      return Action::release;
    }
    if (!queue_.empty()) {
      current_ = std::move(queue_.front());
      queue_.pop_front();
      writing_ = true;
      return Action::write;
    }
    if (end_queued_ && hold_held_) {
      hold_held_ = false;
      return Action::close_and_release;
    }
    return Action::none;
  }

  void act(Action action) {
    switch (action) {
      case Action::none:
        break;
      case Action::write:
        StartWrite(&current_);
        break;
      case Action::close_and_release:
        StartWritesDone();
        RemoveHold();
        break;
      case Action::release:
        RemoveHold();
        break;
    }
  }

  grpc::ClientContext context_;
  HandlerGuard guard_;
  CallCompletion completion_;
  v1::TrackMessage incoming_;
  v1::AnimateRequest current_;  // the request being written

  std::mutex mutex_;  // the write queue
  std::deque<v1::AnimateRequest> queue_;
  bool writing_ = false;
  bool hold_held_ = false;
  bool end_queued_ = false;
  bool aborted_ = false;
};

class SubscribeReactor : public HandoffReactor<grpc::ClientReadReactor<v1::TrackMessage>> {
 public:
  SubscribeReactor(v1::LipSync::Stub& stub, const v1::SubscribeRequest& request, MessageHandler handler,
                   DoneHandler on_done, std::chrono::milliseconds timeout, const std::string& api_key)
      : guard_(std::move(handler)), completion_(std::move(on_done)), request_(request) {
    context_.set_deadline(deadline_after(timeout));
    add_api_key(context_, api_key);
    add_session_metadata(context_, request.session());
    stub.async()->Subscribe(&context_, &request_, this);
    StartRead(&incoming_);
    StartCall();
  }

  void cancel() { context_.TryCancel(); }

  std::optional<grpc::Status> wait_for(std::optional<std::chrono::milliseconds> timeout) {
    return completion_.wait_for(timeout);
  }
  bool done() const { return completion_.done(); }

  void OnReadDone(bool ok) override {
    const HandoffScope handoff = reaction();
    if (ok && guard_.deliver(incoming_, context_)) StartRead(&incoming_);
  }

  // Last: a waiter may destroy this reactor as soon as the call is complete.
  void OnDone(const grpc::Status& status) override {
    last_reaction();
    completion_.complete(guard_.adjust(status));
  }

 private:
  grpc::ClientContext context_;
  HandlerGuard guard_;
  CallCompletion completion_;
  v1::SubscribeRequest request_;
  v1::TrackMessage incoming_;
};

}  // namespace detail

AnimateCall::AnimateCall(std::unique_ptr<detail::AnimateReactor> reactor) : reactor_(std::move(reactor)) {}

AnimateCall::~AnimateCall() {
  if (!reactor_->done()) reactor_->cancel();
  reactor_->wait();
}

bool AnimateCall::send(std::vector<v1::Phoneme> phonemes) { return reactor_->send(std::move(phonemes)); }
bool AnimateCall::send_audio(std::string wav_piece) { return reactor_->send_audio(std::move(wav_piece)); }
void AnimateCall::end() { reactor_->end(); }
void AnimateCall::cancel() { reactor_->cancel(); }
grpc::Status AnimateCall::wait() { return reactor_->wait(); }
bool AnimateCall::done() const { return reactor_->done(); }

SubscribeCall::SubscribeCall(std::unique_ptr<detail::SubscribeReactor> reactor) : reactor_(std::move(reactor)) {}

SubscribeCall::~SubscribeCall() {
  if (!reactor_->done()) reactor_->cancel();
  reactor_->wait_for(std::nullopt);
}

void SubscribeCall::cancel() { reactor_->cancel(); }
grpc::Status SubscribeCall::wait() { return *reactor_->wait_for(std::nullopt); }
std::optional<grpc::Status> SubscribeCall::wait_for(std::chrono::milliseconds timeout) {
  return reactor_->wait_for(timeout);
}
bool SubscribeCall::done() const { return reactor_->done(); }

AnimationClient::AnimationClient(std::string address, ClientOptions options)
    : address_(std::move(address)), options_(options) {
  grpc::ChannelArguments arguments;
  arguments.SetMaxReceiveMessageSize(256 * 1024 * 1024);
  // Each client gets its own connection, so that a load test can spread its streams.
  arguments.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  channel_ = grpc::CreateCustomChannel(address_, channel_credentials(options_.tls), arguments);
  stub_ = v1::LipSync::NewStub(channel_);
}

std::string unreachable_hint(const TlsOptions& tls) {
  return tls.on() ? "(is lipsyncd running there with TLS, and do --ca, --cert and --key match its certificate and "
                    "client CA? see --server)"
                  : "(is lipsyncd running there? if it uses TLS, add --ca FILE or --tls; see --server)";
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

std::unique_ptr<AnimateCall> AnimationClient::start_animate(const v1::AnimationSettings& settings,
                                                            MessageHandler handler, DoneHandler on_done) const {
  return std::unique_ptr<AnimateCall>(new AnimateCall(std::make_unique<detail::AnimateReactor>(
      *stub_, settings, std::move(handler), std::move(on_done), options_.stream_timeout, options_.api_key)));
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

std::unique_ptr<SubscribeCall> AnimationClient::start_subscribe(const std::string& session,
                                                                v1::SubscribeRequest::Start start,
                                                                MessageHandler handler, DoneHandler on_done) const {
  v1::SubscribeRequest request;
  request.set_session(session);
  request.set_start(start);
  return std::unique_ptr<SubscribeCall>(new SubscribeCall(std::make_unique<detail::SubscribeReactor>(
      *stub_, request, std::move(handler), std::move(on_done), options_.stream_timeout, options_.api_key)));
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

void SpokenTrack::add(const v1::SpeakResponse& message) {
  const bool started = header.sample_rate_hz() != 0;
  if (!started && !message.has_header()) throw protocol_error("a Speak message before the SpeakHeader");
  switch (message.kind_case()) {
    case v1::SpeakResponse::kHeader: {
      if (started) throw protocol_error("a second SpeakHeader");
      if (message.header().sample_rate_hz() == 0 || message.header().channels() != 1 ||
          message.header().sample_format() != v1::SAMPLE_FORMAT_PCM_S16LE) {
        throw protocol_error("a SpeakHeader with an audio format other than mono PCM_S16LE at a known rate");
      }
      header = message.header();
      samples.clear();
      samples.reserve(header.sample_count());
      v1::TrackMessage track_header;
      *track_header.mutable_header() = header.track();
      track.add(track_header);
      break;
    }
    case v1::SpeakResponse::kAudio: {
      const v1::AudioChunk& chunk = message.audio();
      const std::string& pcm = chunk.pcm();
      if (chunk.first_sample() != samples.size()) {
        throw protocol_error("an audio chunk starting at sample " + std::to_string(chunk.first_sample()) + " after " +
                             std::to_string(samples.size()) + " samples");
      }
      if (pcm.size() % 2 != 0 || samples.size() + pcm.size() / 2 > header.sample_count()) {
        throw protocol_error("an audio chunk of " + std::to_string(pcm.size()) + " bytes at sample " +
                             std::to_string(samples.size()) + " of " + std::to_string(header.sample_count()));
      }
      for (std::size_t i = 0; i < pcm.size(); i += 2) {
        const auto low = static_cast<std::uint8_t>(pcm[i]);
        const auto high = static_cast<std::uint8_t>(pcm[i + 1]);
        samples.push_back(static_cast<std::int16_t>(static_cast<std::uint16_t>(low | (high << 8))));
      }
      break;
    }
    case v1::SpeakResponse::kFrames:
      track.add_frames(message.frames());
      break;
    case v1::SpeakResponse::kSummary:
      summary = message.summary();
      track.summary = message.summary().track();
      break;
    default:
      throw protocol_error("a Speak message with no content");
  }
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
