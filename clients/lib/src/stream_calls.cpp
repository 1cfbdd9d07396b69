// The client's streams on gRPC's callback API: the producer reactor behind AnimateCall and
// ListenCall, the Subscribe reactor behind SubscribeCall, and AnimationClient's start_animate,
// start_listen and start_subscribe that create them.
//
// A producer reactor keeps a queue of
// requests and at most one write in flight; a hold keeps the call open until
// the caller has sent the end marker (or the stream has failed), so that a
// send() from the caller's thread never races the end of the call. gRPC
// operations are started outside the reactor's mutex, because a RemoveHold may
// run OnDone, which takes it. A message handler that throws cancels its call
// (HandlerGuard); CallCompletion hands the final status to the threads that wait.
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <utility>

#include "call_context.hpp"
#include "lipsync/client/animation_client.hpp"
#include "lipsync/tsan_handoff.hpp"

namespace lipsync::client {

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

/// A producer's stream (Animate, Listen): its settings first, then what the caller sends, then
/// the end marker; TrackMessages come back.
template <class Request>
class ProducerReactor : public HandoffReactor<grpc::ClientBidiReactor<Request, v1::TrackMessage>> {
 public:
  using Base = HandoffReactor<grpc::ClientBidiReactor<Request, v1::TrackMessage>>;
  /// Starts the call on `context` and this reactor (the stub's async method).
  using Start = std::function<void(grpc::ClientContext*, grpc::ClientBidiReactor<Request, v1::TrackMessage>*)>;

  ProducerReactor(const Start& start, Request settings, const std::string& session, MessageHandler handler,
                  DoneHandler on_done, std::chrono::milliseconds timeout, const std::string& api_key)
      : guard_(std::move(handler)), completion_(std::move(on_done)) {
    context_.set_deadline(deadline_after(timeout));
    add_api_key(context_, api_key);
    add_session_metadata(context_, session);
    start(&context_, this);
    this->AddHold();
    hold_held_ = true;
    queue_.push_back(std::move(settings));
    act(next_action_locked());
    this->StartRead(&incoming_);
    this->StartCall();
  }

  /// Queues `request`; false once the stream has ended.
  bool send(Request request) { return enqueue(std::move(request), false); }

  /// Queues the end marker and closes the sending side.
  void end(Request end_marker) { enqueue(std::move(end_marker), true); }

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
    const HandoffScope handoff = this->reaction();
    if (ok && guard_.deliver(incoming_, context_)) {
      this->StartRead(&incoming_);
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
    const HandoffScope handoff = this->reaction();
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
    this->last_reaction();
    completion_.complete(guard_.adjust(status));
  }

 private:
  enum class Action { none, write, close_and_release, release };

  bool enqueue(Request request, bool is_end) {
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
        this->StartWrite(&current_);
        break;
      case Action::close_and_release:
        this->StartWritesDone();
        this->RemoveHold();
        break;
      case Action::release:
        this->RemoveHold();
        break;
    }
  }

  grpc::ClientContext context_;
  HandlerGuard guard_;
  CallCompletion completion_;
  v1::TrackMessage incoming_;
  Request current_;  // the request being written

  std::mutex mutex_;  // the write queue
  std::deque<Request> queue_;
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

AnimateCall::AnimateCall(std::unique_ptr<detail::ProducerReactor<v1::AnimateRequest>> reactor)
    : reactor_(std::move(reactor)) {}

AnimateCall::~AnimateCall() {
  if (!reactor_->done()) reactor_->cancel();
  reactor_->wait();
}

bool AnimateCall::send(std::vector<v1::Phoneme> phonemes) {
  v1::AnimateRequest request;
  auto* chunk = request.mutable_phonemes();
  chunk->mutable_phonemes()->Reserve(static_cast<int>(phonemes.size()));
  for (v1::Phoneme& phoneme : phonemes) *chunk->add_phonemes() = std::move(phoneme);
  return reactor_->send(std::move(request));
}
bool AnimateCall::send_audio(std::string wav_piece) {
  v1::AnimateRequest request;
  *request.mutable_audio()->mutable_wav() = std::move(wav_piece);
  return reactor_->send(std::move(request));
}
void AnimateCall::end() {
  v1::AnimateRequest request;
  request.mutable_end();
  reactor_->end(std::move(request));
}
void AnimateCall::cancel() { reactor_->cancel(); }
grpc::Status AnimateCall::wait() { return reactor_->wait(); }
bool AnimateCall::done() const { return reactor_->done(); }

ListenCall::ListenCall(std::unique_ptr<detail::ProducerReactor<v1::ListenRequest>> reactor)
    : reactor_(std::move(reactor)) {}

ListenCall::~ListenCall() {
  if (!reactor_->done()) reactor_->cancel();
  reactor_->wait();
}

bool ListenCall::send_audio(std::string bytes) {
  v1::ListenRequest request;
  *request.mutable_audio()->mutable_data() = std::move(bytes);
  return reactor_->send(std::move(request));
}
bool ListenCall::send_words(v1::ListenWords words) {
  v1::ListenRequest request;
  *request.mutable_words() = std::move(words);
  return reactor_->send(std::move(request));
}
void ListenCall::end() {
  v1::ListenRequest request;
  request.mutable_end();
  reactor_->end(std::move(request));
}
void ListenCall::cancel() { reactor_->cancel(); }
grpc::Status ListenCall::wait() { return reactor_->wait(); }
bool ListenCall::done() const { return reactor_->done(); }

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

std::unique_ptr<AnimateCall> AnimationClient::start_animate(const v1::AnimationSettings& settings,
                                                            MessageHandler handler, DoneHandler on_done) const {
  v1::AnimateRequest first;
  *first.mutable_settings() = settings;
  auto* stub = stub_.get();
  return std::unique_ptr<AnimateCall>(new AnimateCall(std::make_unique<detail::ProducerReactor<v1::AnimateRequest>>(
      [stub](grpc::ClientContext* context, grpc::ClientBidiReactor<v1::AnimateRequest, v1::TrackMessage>* reactor) {
        stub->async()->Animate(context, reactor);
      },
      std::move(first), settings.session(), std::move(handler), std::move(on_done), options_.stream_timeout,
      options_.api_key)));
}

std::unique_ptr<ListenCall> AnimationClient::start_listen(const v1::ListenSettings& settings, MessageHandler handler,
                                                          DoneHandler on_done) const {
  v1::ListenRequest first;
  *first.mutable_settings() = settings;
  auto* stub = stub_.get();
  return std::unique_ptr<ListenCall>(new ListenCall(std::make_unique<detail::ProducerReactor<v1::ListenRequest>>(
      [stub](grpc::ClientContext* context, grpc::ClientBidiReactor<v1::ListenRequest, v1::TrackMessage>* reactor) {
        stub->async()->Listen(context, reactor);
      },
      std::move(first), settings.animation().session(), std::move(handler), std::move(on_done), options_.stream_timeout,
      options_.api_key)));
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

}  // namespace lipsync::client
