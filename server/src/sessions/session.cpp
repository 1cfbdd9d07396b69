#include "session.hpp"

#include <algorithm>

#include "lipsync/excerpt.hpp"

namespace {

/// Bytes of mesh positions in a batch (0 for every stream without the mesh output); O(1).
std::size_t mesh_bytes(const lipsync::server::Message& batch) {
  const lipsync::v1::TrackMessage& message = batch->message();
  if (!message.has_frames()) return 0;
  return static_cast<std::size_t>(message.frames().mesh_positions_size()) * sizeof(float) +
         message.frames().mesh_positions_int16().size();
}

}  // namespace

namespace lipsync::server {

void EndedSessions::add(Ended ended) {
  std::lock_guard lock(mutex_);
  ended_.push_back(std::move(ended));
}

std::vector<EndedSessions::Ended> EndedSessions::take_until(std::chrono::steady_clock::time_point cutoff) {
  std::lock_guard lock(mutex_);
  std::vector<Ended> taken;
  while (!ended_.empty() && ended_.front().at <= cutoff) {
    taken.push_back(std::move(ended_.front()));
    ended_.pop_front();
  }
  return taken;
}

Session::Session(std::string name, Message header, std::size_t replay_frames, std::string key,
                 std::shared_ptr<EndedSessions> ended)
    : name_(std::move(name)),
      header_(std::move(header)),
      replay_frames_(replay_frames),
      key_(std::move(key)),
      ended_sessions_(std::move(ended)) {}

void Session::publish(const Message& batch, std::size_t frames) {
  std::lock_guard lock(mutex_);
  if (state_ != State::live) return;
  replay_.emplace_back(batch, frames);
  replay_held_ += frames;
  replay_mesh_bytes_ += mesh_bytes(batch);
  while (!replay_.empty() && (replay_held_ > replay_frames_ || replay_mesh_bytes_ > kMaxReplayMeshBytes)) {
    replay_held_ -= replay_.front().second;
    replay_mesh_bytes_ -= mesh_bytes(replay_.front().first);
    replay_.pop_front();
  }
  std::erase_if(subscribers_, [&](const std::shared_ptr<Outbox>& outbox) { return !outbox->push(batch, frames); });
}

void Session::finish(const Message& summary) {
  std::lock_guard lock(mutex_);
  if (state_ != State::live) return;
  summary_ = summary;
  for (const auto& outbox : subscribers_) {
    outbox->push(summary);
    outbox->close(grpc::Status::OK);
  }
  end_locked(State::finished);
}

void Session::fail(const std::string& reason) {
  std::lock_guard lock(mutex_);
  if (state_ != State::live) return;
  failure_ = reason;
  for (const auto& outbox : subscribers_) outbox->close(aborted_status_locked());
  end_locked(State::failed);
}

void Session::end_locked(State state) {
  state_ = state;
  ended_at_ = std::chrono::steady_clock::now();
  subscribers_.clear();
  if (ended_sessions_) ended_sessions_->add({key_, weak_from_this(), ended_at_});
}

grpc::Status Session::aborted_status_locked() const {
  return {grpc::StatusCode::ABORTED, "session " + excerpt(name_) + ": " + failure_};
}

grpc::Status Session::attach(const std::shared_ptr<Outbox>& outbox, bool from_beginning, std::size_t max_subscribers) {
  std::lock_guard lock(mutex_);
  if (state_ == State::failed) return aborted_status_locked();
  if (state_ == State::live && subscribers_.size() >= max_subscribers) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            "session " + excerpt(name_) + " already has " + std::to_string(subscribers_.size()) +
                " subscribers (--max-subscribers-per-session=" + std::to_string(max_subscribers) + ")"};
  }
  // The replay does not count toward the subscriber's bound: it is shared and
  // already held; only frames that arrive later can pile up.
  outbox->push(header_);
  if (from_beginning) {
    for (const auto& [batch, frames] : replay_) outbox->push(batch);
  }
  if (state_ == State::finished) {
    outbox->push(summary_);
    outbox->close(grpc::Status::OK);
  } else {
    subscribers_.push_back(outbox);
  }
  return grpc::Status::OK;
}

void Session::detach(const Outbox* outbox) {
  std::lock_guard lock(mutex_);
  std::erase_if(subscribers_, [&](const std::shared_ptr<Outbox>& held) { return held.get() == outbox; });
}

void Session::set_audio_wav(std::shared_ptr<const std::string> wav) {
  std::lock_guard lock(mutex_);
  audio_wav_ = std::move(wav);
}

std::shared_ptr<const std::string> Session::audio_wav() const {
  std::lock_guard lock(mutex_);
  return audio_wav_;
}

bool Session::live() const {
  std::lock_guard lock(mutex_);
  return state_ == State::live;
}

std::size_t Session::subscriber_count() const {
  std::lock_guard lock(mutex_);
  return subscribers_.size();
}

SessionRegistry::SessionRegistry(std::size_t max_sessions, std::size_t replay_frames,
                                 std::chrono::milliseconds retention)
    : max_sessions_(max_sessions), replay_frames_(replay_frames), retention_(retention) {}

void SessionRegistry::sweep_locked() {
  for (const EndedSessions::Ended& ended : ended_->take_until(std::chrono::steady_clock::now() - retention_)) {
    // The name may have been taken since by a new producer (open replaces an ended session).
    const auto it = sessions_.find(ended.key);
    if (it != sessions_.end() && it->second == ended.session.lock()) sessions_.erase(it);
  }
}

grpc::Status SessionRegistry::open(const std::string& name, const Message& header, std::shared_ptr<Session>& out,
                                   const std::string& key) {
  std::lock_guard lock(mutex_);
  sweep_locked();
  if (const auto it = sessions_.find(key.empty() ? name : key); it != sessions_.end()) {
    if (it->second->live()) {
      return {grpc::StatusCode::ALREADY_EXISTS, "session " + excerpt(name) + " already has a live producer"};
    }
    sessions_.erase(it);
  }
  if (sessions_.size() >= max_sessions_) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED, "the server already holds " + std::to_string(sessions_.size()) +
                                                      " sessions (--max-sessions=" + std::to_string(max_sessions_) +
                                                      ")"};
  }
  const std::string& filed_under = key.empty() ? name : key;
  out = std::make_shared<Session>(name, header, replay_frames_, filed_under, ended_);
  sessions_.emplace(filed_under, out);
  return grpc::Status::OK;
}

std::shared_ptr<Session> SessionRegistry::find(const std::string& name) {
  std::lock_guard lock(mutex_);
  sweep_locked();
  const auto it = sessions_.find(name);
  return it == sessions_.end() ? nullptr : it->second;
}

std::size_t SessionRegistry::size() {
  std::lock_guard lock(mutex_);
  sweep_locked();
  return sessions_.size();
}

SessionRegistry::Counts SessionRegistry::counts() {
  const auto all = counts_by([](const std::string&) { return std::string(); });
  return all.empty() ? Counts{} : all.begin()->second;
}

std::map<std::string, SessionRegistry::Counts> SessionRegistry::counts_by(
    const std::function<std::string(const std::string& key)>& group_of) {
  std::lock_guard lock(mutex_);
  sweep_locked();
  std::map<std::string, Counts> groups;
  for (const auto& [key, session] : sessions_) {
    Counts& counts = groups[group_of(key)];
    ++(session->live() ? counts.live : counts.ended);
    counts.subscribers += session->subscriber_count();
  }
  return groups;
}

}  // namespace lipsync::server
