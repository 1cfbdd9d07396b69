// Sessions: one Animate stream (the producer) publishing its frames under a
// name, any number of Subscribe streams following them.
//
// The producer pushes each message once; the session hands the same immutable
// message (a shared_ptr) to every subscriber's bounded Outbox and to a replay
// buffer that keeps the header and the last `replay_frames` frames for late
// joiners. Subscribers write the message's bytes, serialised once and shared
// (outbox.hpp), so a batch is encoded once for any number of subscribers. Pushing never waits: a subscriber whose
// outbox overflows is ended with RESOURCE_EXHAUSTED by its outbox and dropped from the session, and the producer and
// the other subscribers go on at full speed.
//
// A mesh session's replay is also bounded by the bytes of mesh positions it
// holds (kMaxReplayMeshBytes): its frames are tens of kilobytes each. Sessions
// without the mesh hold no such bytes and are bounded by frames alone.
//
// A finished (or failed) session stays joinable for the retention time, then
// the registry forgets it; a new producer may then reuse the name. Every
// session is kept for the same time, so the ones to forget are always those
// that ended first: sessions report their end to a queue (EndedSessions), and
// the registry's sweep, which runs on every open and lookup, takes only what
// has expired from its front. Before, each sweep visited every session held,
// under the registry's lock: at 1,000 producers with 3 subscribers each
// (~4,000 sessions held, ~1,300 opens and lookups a second) that lock was held
// a large part of the time, and Subscribe calls queued behind it.
#pragma once

#include <chrono>
#include <cstddef>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "rpc/outbox.hpp"

namespace lipsync::server {

class Session;

/// The sessions that have ended, oldest first (two that end at the same moment
/// on two threads may be queued in either order: one is then forgotten a few
/// microseconds late). Its lock is a leaf: taken under a session's lock or the
/// registry's, and nothing is locked under it.
class EndedSessions {
 public:
  struct Ended {
    std::string key;  ///< what the registry files the session under
    std::weak_ptr<const Session> session;
    std::chrono::steady_clock::time_point at;
  };
  void add(Ended ended);
  /// Removes and returns the sessions that ended at or before `cutoff`, oldest first.
  std::vector<Ended> take_until(std::chrono::steady_clock::time_point cutoff);

 private:
  std::mutex mutex_;
  std::deque<Ended> ended_;
};

class Session : public std::enable_shared_from_this<Session> {
 public:
  static constexpr std::size_t kMaxReplayMeshBytes = std::size_t{64} << 20;

  /// `ended`, if given, hears of the session's end, under `key`.
  Session(std::string name, Message header, std::size_t replay_frames, std::string key = {},
          std::shared_ptr<EndedSessions> ended = nullptr);

  const std::string& name() const { return name_; }

  // Producer side.
  void publish(const Message& batch, std::size_t frames);
  void finish(const Message& summary);
  void fail(const std::string& reason);

  /// Adds a subscriber: queues the header, the replay (if from_beginning) and,
  /// for an ended session, the summary or the ABORTED status. Returns
  /// RESOURCE_EXHAUSTED if the session already has `max_subscribers`.
  grpc::Status attach(const std::shared_ptr<Outbox>& outbox, bool from_beginning, std::size_t max_subscribers);
  void detach(const Outbox* outbox);

  bool live() const;
  std::size_t subscriber_count() const;

  /// The session's sound as a WAV file (a Speak session's voice, for the viewer's /audio), kept
  /// as long as the session; null when it has none.
  void set_audio_wav(std::shared_ptr<const std::string> wav);
  std::shared_ptr<const std::string> audio_wav() const;

 private:
  enum class State { live, finished, failed };

  void end_locked(State state);
  grpc::Status aborted_status_locked() const;

  const std::string name_;
  const Message header_;
  const std::size_t replay_frames_;
  const std::string key_;
  const std::shared_ptr<EndedSessions> ended_sessions_;
  mutable std::mutex mutex_;
  State state_ = State::live;
  std::deque<std::pair<Message, std::size_t>> replay_;  // batch, frames
  std::size_t replay_held_ = 0;
  std::size_t replay_mesh_bytes_ = 0;
  Message summary_;
  std::string failure_;
  std::chrono::steady_clock::time_point ended_at_;
  std::vector<std::shared_ptr<Outbox>> subscribers_;
  std::shared_ptr<const std::string> audio_wav_;
};

class SessionRegistry {
 public:
  SessionRegistry(std::size_t max_sessions, std::size_t replay_frames, std::chrono::milliseconds retention);

  /// Opens a session for a producer. ALREADY_EXISTS if a live producer holds the
  /// name; RESOURCE_EXHAUSTED beyond max_sessions. An ended session of that name
  /// is replaced. `key` (default: the name) is what the registry files it under:
  /// the name in its tenant's namespace (Caller::session_key); messages show the name.
  grpc::Status open(const std::string& name, const Message& header, std::shared_ptr<Session>& out,
                    const std::string& key = {});
  /// nullptr if there is no session under `key` (or it has expired).
  std::shared_ptr<Session> find(const std::string& key);
  std::size_t size();
  /// Sessions held by state (live: a producer is streaming; ended: finished or failed, still
  /// retained) and their subscribers, for the metrics.
  struct Counts {
    std::size_t live = 0;
    std::size_t ended = 0;
    std::size_t subscribers = 0;
  };
  Counts counts();
  /// The counts per group, the group of a session being `group_of(key)` (its tenant).
  std::map<std::string, Counts> counts_by(const std::function<std::string(const std::string& key)>& group_of);

 private:
  /// Forgets the sessions that ended more than the retention time ago: O(those).
  void sweep_locked();

  const std::size_t max_sessions_;
  const std::size_t replay_frames_;
  const std::chrono::milliseconds retention_;
  const std::shared_ptr<EndedSessions> ended_ = std::make_shared<EndedSessions>();
  std::mutex mutex_;
  std::map<std::string, std::shared_ptr<Session>, std::less<>> sessions_;
};

}  // namespace lipsync::server
