// grpc_baseline_server: a bare gRPC server for lipsyncd's load test.
//
// It implements lipsync.v1.LipSync/Animate the way lipsyncd does (callback
// API, one ServerBidiReactor per stream, a queue with one write in flight and
// Finish only when none is) and answers with messages of the same shape: a
// TrackHeader, FrameBatches of constant frames on the uniform grid (t_us,
// kinds, 16 channel floats and/or 52 ARKit floats per frame, as the settings'
// outputs ask), and a TrackSummary. Like lipsyncd with lookahead 7, which
// computes a segment's frames once the 7th segment after it is known, a chunk
// releases the frames up to the end of the phoneme 7 places back (before the
// start of the one 6 places back), and `end` releases the rest; batches hold
// at most 512 frames. (lipsyncd still sends a few more batches per utterance:
// a closure, or a phoneme shorter than a frame interval, gets a key frame of
// its own there, so none of its releases is empty.) There is no engine, no
// session, no validation and no admission limit: what it costs is what gRPC
// and protobuf cost, so `lipsync loadtest --no-verify` against it gives the
// ceiling lipsyncd is compared with (tools/perf/server_loadtest.sh).
//
// Fan-out: an Animate stream whose settings name a session also publishes its
// messages there, and Subscribe sends a session's messages (all of them from
// the start, then each as it comes) to any number of streams. As in lipsyncd,
// each message is serialised once into a grpc::ByteBuffer that every
// subscriber's write shares (Subscribe is a raw method), so N subscribers cost
// what N writes of the same bytes cost. A session is forgotten once its producer
// has ended the retention ago (10 s, as lipsyncd's default), when the next session
// opens; an unknown one is NOT_FOUND. tests/clients/baseline_server_test.cpp
// checks these promises against lipsyncd.
//
// With --busy-ns-per-frame N it also spins on the clock for N ns per frame it
// releases (once, however many streams receive the frame; 0 by default): a
// server that costs the baseline's transport plus a known amount of work per
// frame, to find how much extra work per frame accounts for lipsyncd's
// throughput in fast mode (docs/performance.md, "What fast mode's gap is made
// of").
//
//   grpc_baseline_server [--listen 127.0.0.1:0] [--session-retention-ms 10000] [--busy-ns-per-frame 0]
//
// Prints "listening on HOST:PORT" on stdout; SIGINT/SIGTERM stop it.
#include <absl/synchronization/mutex.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/impl/codegen/proto_utils.h>
#include <signal.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

// The generated base declares sync-API overloads of Animate that the callback
// override hides on purpose (as in server/src/rpc/service.hpp).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Woverloaded-virtual"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace {

namespace v1 = lipsync::v1;
using Message = std::shared_ptr<const v1::TrackMessage>;

constexpr int kChannels = 16;
constexpr int kArkit = 52;
constexpr std::size_t kLookahead = 7;
constexpr std::int64_t kMaxFramesPerBatch = 512;

/// Spins on the clock for `duration` (nothing if it is zero or less).
void busy_for(std::chrono::nanoseconds duration) {
  if (duration <= std::chrono::nanoseconds::zero()) return;
  const auto until = std::chrono::steady_clock::now() + duration;
  while (std::chrono::steady_clock::now() < until) {
  }
}

/// The outgoing side of a stream: one write in flight, Finish once nothing is
/// queued. `Item` is what the stream writes (a typed message or bytes).
template <class Item, class Reactor>
class Writer {
 public:
  explicit Writer(Reactor& reactor) : reactor_(reactor) {}

  void push(Item item) {
    {
      std::lock_guard lock(mutex_);
      if (status_) return;
      queue_.push_back(std::move(item));
    }
    pump();
  }
  void close(const grpc::Status& status) {
    {
      std::lock_guard lock(mutex_);
      if (!status_) status_ = status;
    }
    pump();
  }
  void abort(const grpc::Status& status) {
    {
      std::lock_guard lock(mutex_);
      queue_.clear();
      if (!status_) status_ = status;
    }
    pump();
  }
  void on_write_done(bool ok) {
    {
      std::lock_guard lock(mutex_);
      writing_ = false;
      if (!ok) {
        queue_.clear();
        if (!status_) status_ = grpc::Status(grpc::StatusCode::CANCELLED, "the client went away");
      }
    }
    pump();
  }

 private:
  void pump() {
    bool write = false;
    bool finish = false;
    grpc::Status status;
    {
      std::lock_guard lock(mutex_);
      if (writing_ || finish_called_) return;
      if (!queue_.empty()) {
        in_flight_ = std::move(queue_.front());
        queue_.pop_front();
        writing_ = true;
        write = true;
      } else if (status_) {
        finish_called_ = true;
        finish = true;
        status = *status_;
      }
    }
    if (write) {
      reactor_.StartWrite(pointer(in_flight_));
    } else if (finish) {
      reactor_.Finish(status);
    }
  }
  static const grpc::ByteBuffer* pointer(const grpc::ByteBuffer& bytes) { return &bytes; }
  static const v1::TrackMessage* pointer(const Message& message) { return message.get(); }

  Reactor& reactor_;
  std::mutex mutex_;
  std::deque<Item> queue_;
  Item in_flight_;
  bool writing_ = false;
  bool finish_called_ = false;
  std::optional<grpc::Status> status_;
};

class SubscribeReactor;

/// One producer's messages, serialised once, and the streams following them.
struct Session {
  std::string name;
  std::uint64_t id = 0;  // which opening of its name (SessionMap)
  std::mutex mutex;
  std::vector<grpc::ByteBuffer> messages;
  std::vector<SubscribeReactor*> subscribers;
  std::optional<std::chrono::steady_clock::time_point> ended_at;
};

/// The sessions by name. Every session is kept for the same retention after
/// it ends, so they expire in the order they ended: opening one forgets the expired
/// at the front of that order, without visiting the others (as lipsyncd's registry
/// does; a sweep of every session held, ~8,000 at 2,000 sessions, had made the
/// baseline's tail with subscribers longer than lipsyncd's).
class SessionMap {
 public:
  explicit SessionMap(std::chrono::milliseconds retention) : retention_(retention) {}

  std::shared_ptr<Session> open(const std::string& name) {
    std::lock_guard lock(mutex_);
    const auto now = std::chrono::steady_clock::now();
    while (!ended_.empty() && now - ended_.front().at > retention_) {
      const auto it = sessions_.find(ended_.front().name);
      // The name may have been opened again since: only the session that ended goes.
      if (it != sessions_.end() && it->second->id == ended_.front().id) sessions_.erase(it);
      ended_.pop_front();
    }
    auto session = std::make_shared<Session>();
    session->name = name;
    session->id = ++opened_;
    sessions_[name] = session;
    return session;
  }
  std::shared_ptr<Session> find(const std::string& name) {
    std::lock_guard lock(mutex_);
    const auto it = sessions_.find(name);
    return it == sessions_.end() ? nullptr : it->second;
  }
  /// `session` ended at `at`.
  void ended(const Session& session, std::chrono::steady_clock::time_point at) {
    std::lock_guard lock(mutex_);
    ended_.push_back({session.name, session.id, at});
  }

 private:
  struct Ended {
    std::string name;
    std::uint64_t id;
    std::chrono::steady_clock::time_point at;
  };
  const std::chrono::milliseconds retention_;
  std::mutex mutex_;
  std::uint64_t opened_ = 0;
  std::map<std::string, std::shared_ptr<Session>> sessions_;
  std::deque<Ended> ended_;
};

class SubscribeReactor final : public grpc::ServerWriteReactor<grpc::ByteBuffer> {
 public:
  SubscribeReactor(SessionMap& sessions, const grpc::ByteBuffer& raw_request) : writer_(*this) {
    v1::SubscribeRequest request;
    grpc::ByteBuffer bytes = raw_request;
    if (!grpc::SerializationTraits<v1::SubscribeRequest>::Deserialize(&bytes, &request).ok()) {
      writer_.close(grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "not a SubscribeRequest"));
      return;
    }
    session_ = sessions.find(request.session());
    if (!session_) {
      writer_.close(grpc::Status(grpc::StatusCode::NOT_FOUND, "no session '" + request.session() + "'"));
      return;
    }
    std::lock_guard lock(session_->mutex);
    for (const grpc::ByteBuffer& message : session_->messages) writer_.push(message);
    if (session_->ended_at) {
      writer_.close(grpc::Status::OK);
    } else {
      session_->subscribers.push_back(this);
    }
  }

  /// Called under the session's lock.
  void push(const grpc::ByteBuffer& message) { writer_.push(message); }
  void close() { writer_.close(grpc::Status::OK); }

  void OnWriteDone(bool ok) override { writer_.on_write_done(ok); }
  void OnCancel() override { writer_.abort(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled")); }
  void OnDone() override {
    if (session_) {
      std::lock_guard lock(session_->mutex);
      std::erase(session_->subscribers, this);
    }
    delete this;
  }

 private:
  friend class Writer<grpc::ByteBuffer, SubscribeReactor>;
  Writer<grpc::ByteBuffer, SubscribeReactor> writer_;
  std::shared_ptr<Session> session_;
};

class AnimateReactor final : public grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage> {
 public:
  AnimateReactor(SessionMap& sessions, std::chrono::nanoseconds busy_per_frame)
      : sessions_(sessions), busy_per_frame_(busy_per_frame), writer_(*this) {
    StartRead(&request_);
  }

  void OnReadDone(bool ok) override {
    if (!ok) {
      close(ended_ ? grpc::Status::OK
                   : grpc::Status(grpc::StatusCode::INVALID_ARGUMENT, "the client closed the stream before `end`"));
      end_session();
      return;
    }
    if (request_.has_settings()) {
      start(request_.settings());
    } else if (request_.has_phonemes()) {
      for (const v1::Phoneme& phoneme : request_.phonemes().phonemes()) {
        starts_.push_back(phoneme.start_us());
        end_us_ = std::max(end_us_, phoneme.end_us());
      }
      // With N phonemes known, lipsyncd's renderer releases the frames of phoneme N − 8.
      if (starts_.size() > kLookahead) release_before(starts_[starts_.size() - kLookahead]);
    } else if (request_.has_end()) {
      release_before(end_us_ + 1);
      auto summary = std::make_shared<v1::TrackMessage>();
      summary->mutable_summary()->set_frames(next_frame_);
      summary->mutable_summary()->set_phonemes(starts_.size());
      summary->mutable_summary()->set_duration_us(end_us_);
      push(std::move(summary));
      end_session();
      ended_ = true;
    }
    StartRead(&request_);
  }

  void OnWriteDone(bool ok) override { writer_.on_write_done(ok); }
  void OnCancel() override {
    writer_.abort(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
    end_session();
  }
  void OnDone() override { delete this; }

 private:
  void start(const v1::AnimationSettings& settings) {
    fps_ = settings.fps() == 0 ? 30 : settings.fps();
    const bool neither = !settings.outputs().channels() && !settings.outputs().arkit();
    channels_ = neither || settings.outputs().channels();
    arkit_ = neither || settings.outputs().arkit();
    auto header = std::make_shared<v1::TrackMessage>();
    v1::TrackHeader& h = *header->mutable_header();
    h.set_model("default");
    h.set_fps(fps_);
    h.set_lookahead(kLookahead);
    h.set_session(settings.session());
    if (!settings.session().empty()) session_ = sessions_.open(settings.session());
    if (channels_) {
      for (int c = 0; c < kChannels; ++c) h.add_channels("channel_" + std::to_string(c));
    }
    if (arkit_) {
      for (int a = 0; a < kArkit; ++a) h.add_arkit_names("arkit_" + std::to_string(a));
    }
    push(std::move(header));
  }

  std::int64_t frame_time(std::int64_t index) const {
    return static_cast<std::int64_t>(std::llround(static_cast<double>(index) * 1e6 / fps_));
  }

  /// Sends the grid frames before `limit_us`, in batches of at most 512.
  void release_before(std::int64_t limit_us) {
    while (frame_time(next_frame_) < limit_us) {
      auto message = std::make_shared<v1::TrackMessage>();
      v1::FrameBatch& batch = *message->mutable_frames();
      batch.set_first_frame(static_cast<std::uint64_t>(next_frame_));
      std::int64_t count = 0;
      while (count < kMaxFramesPerBatch && frame_time(next_frame_ + count) < limit_us) ++count;
      batch.mutable_t_us()->Reserve(static_cast<int>(count));
      batch.mutable_kinds()->Reserve(static_cast<int>(count));
      for (std::int64_t i = 0; i < count; ++i) {
        batch.add_t_us(frame_time(next_frame_ + i));
        batch.add_kinds(v1::FRAME_KIND_UNIFORM);
      }
      if (channels_) batch.mutable_values()->Resize(static_cast<int>(count) * kChannels, 0.25f);
      if (arkit_) batch.mutable_arkit()->Resize(static_cast<int>(count) * kArkit, 0.125f);
      next_frame_ += count;
      busy_for(busy_per_frame_ * count);
      push(std::move(message));
    }
  }

  /// To this stream, and serialised once to the session's subscribers.
  void push(Message message) {
    if (session_) {
      grpc::ByteBuffer bytes;
      bool own_buffer = false;
      (void)grpc::SerializationTraits<v1::TrackMessage>::Serialize(*message, &bytes, &own_buffer);
      std::lock_guard lock(session_->mutex);
      session_->messages.push_back(bytes);
      for (SubscribeReactor* subscriber : session_->subscribers) subscriber->push(bytes);
    }
    writer_.push(std::move(message));
  }

  void close(const grpc::Status& status) { writer_.close(status); }

  void end_session() {
    if (!session_) return;
    std::chrono::steady_clock::time_point ended_at;
    {
      std::lock_guard lock(session_->mutex);
      if (session_->ended_at) return;
      ended_at = std::chrono::steady_clock::now();
      session_->ended_at = ended_at;
      for (SubscribeReactor* subscriber : session_->subscribers) subscriber->close();
      session_->subscribers.clear();
    }
    sessions_.ended(*session_, ended_at);
  }

  friend class Writer<Message, AnimateReactor>;
  SessionMap& sessions_;
  const std::chrono::nanoseconds busy_per_frame_;
  std::shared_ptr<Session> session_;
  Writer<Message, AnimateReactor> writer_;
  v1::AnimateRequest request_;
  std::uint32_t fps_ = 30;
  bool channels_ = true;
  bool arkit_ = true;
  bool ended_ = false;
  std::vector<std::int64_t> starts_;
  std::int64_t end_us_ = 0;
  std::int64_t next_frame_ = 0;
};

class BaselineService final : public v1::LipSync::WithRawCallbackMethod_Subscribe<v1::LipSync::CallbackService> {
 public:
  BaselineService(std::chrono::milliseconds retention, std::chrono::nanoseconds busy_per_frame)
      : sessions_(retention), busy_per_frame_(busy_per_frame) {}

 private:
  grpc::ServerBidiReactor<v1::AnimateRequest, v1::TrackMessage>* Animate(
      grpc::CallbackServerContext* /*context*/) override {
    return new AnimateReactor(sessions_, busy_per_frame_);
  }
  grpc::ServerWriteReactor<grpc::ByteBuffer>* Subscribe(grpc::CallbackServerContext* /*context*/,
                                                        const grpc::ByteBuffer* request) override {
    return new SubscribeReactor(sessions_, *request);
  }

  SessionMap sessions_;
  const std::chrono::nanoseconds busy_per_frame_;
};
#pragma GCC diagnostic pop

}  // namespace

int main(int argc, char** argv) {
  std::string listen = "127.0.0.1:0";
  long retention_ms = 10'000;
  long busy_ns_per_frame = 0;
  // A whole number in [0, max] for `option`, or a message on stderr and nullopt.
  const auto whole_number = [](const std::string& option, const std::string& value, long max) -> std::optional<long> {
    char* end = nullptr;
    errno = 0;
    const long number = std::strtol(value.c_str(), &end, 10);
    if (value.empty() || *end != '\0' || errno != 0 || number < 0 || number > max) {
      std::cerr << "grpc_baseline_server: " << option << " must be 0 to " << max << ", not '" << value << "'\n";
      return std::nullopt;
    }
    return number;
  };
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if ((arg == "--listen" || arg == "--session-retention-ms" || arg == "--busy-ns-per-frame") && i + 1 == argc) {
      std::cerr << "grpc_baseline_server: " << arg << " needs a value\n";
      return 2;
    }
    if (arg == "--listen") {
      listen = argv[++i];
    } else if (arg == "--session-retention-ms") {
      const std::optional<long> number = whole_number(arg, argv[++i], 86'400'000);
      if (!number) return 2;
      retention_ms = *number;
    } else if (arg == "--busy-ns-per-frame") {
      const std::optional<long> number = whole_number(arg, argv[++i], 1'000'000);
      if (!number) return 2;
      busy_ns_per_frame = *number;
    } else if (arg == "--help" || arg == "-h") {
      std::cout
          << "grpc_baseline_server [--listen 127.0.0.1:0] [--session-retention-ms 10000] [--busy-ns-per-frame 0]\n";
      return 0;
    } else {
      std::cerr << "grpc_baseline_server: unknown argument '" << arg << "'\n";
      return 2;
    }
  }
  // The same process setting as lipsyncd (server/src/main.cpp): Debian's abseil leaves the
  // deadlock detection of gRPC's Mutexes on; both servers turn it off, so that the comparison
  // is of the same transport.
  absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  BaselineService service{std::chrono::milliseconds(retention_ms), std::chrono::nanoseconds(busy_ns_per_frame)};
  grpc::ServerBuilder builder;
  int port = 0;
  builder.AddListeningPort(listen, grpc::InsecureServerCredentials(), &port);
  builder.RegisterService(&service);
  std::unique_ptr<grpc::Server> server = builder.BuildAndStart();
  if (!server || port == 0) {
    std::cerr << "grpc_baseline_server: cannot listen on " << listen << '\n';
    return 1;
  }
  std::cout << "listening on " << listen.substr(0, listen.rfind(':')) << ':' << port << std::endl;
  int signal = 0;
  sigwait(&signals, &signal);
  server->Shutdown(std::chrono::system_clock::now() + std::chrono::milliseconds(500));
  server->Wait();
  return 0;
}
