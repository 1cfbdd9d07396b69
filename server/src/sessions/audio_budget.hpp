// The sound that sessions keep for their viewers (/audio?session=NAME): a Speak session's voice
// and the WAV a producer attaches to its Animate stream. One session may hold up to 32 MiB of it,
// and lipsyncd holds up to 10,000 sessions, so without a bound of their own together they could
// hold hundreds of gigabytes. AudioBudget is that bound (--max-session-audio-bytes): bytes are
// reserved before they are kept, while an attachment is still arriving, and released when the last
// owner lets go of them (the session expires, or the stream fails before it kept its audio).
//
// Contract: try_reserve(n) succeeds only while held + n <= limit; every reserved byte is released
// once, by release() or by the string keep() made of it; held_bytes() is never above the limit.
#pragma once

#include <cstddef>
#include <memory>
#include <mutex>
#include <string>

namespace lipsync::server {

class AudioBudget : public std::enable_shared_from_this<AudioBudget> {
 public:
  explicit AudioBudget(std::size_t limit_bytes) : limit_bytes_(limit_bytes) {}

  /// Reserves `bytes` when they fit under the limit with what is held; false (nothing reserved)
  /// when they do not.
  bool try_reserve(std::size_t bytes);
  /// Gives back `bytes` reserved before.
  void release(std::size_t bytes) noexcept;
  /// `wav`, whose size is reserved already, as a shared string that gives its bytes back to the
  /// budget when its last owner lets go of it. The budget must be owned by a shared_ptr.
  std::shared_ptr<const std::string> keep(std::string wav);

  std::size_t held_bytes() const;
  std::size_t limit_bytes() const { return limit_bytes_; }

 private:
  const std::size_t limit_bytes_;
  mutable std::mutex mutex_;
  std::size_t held_bytes_ = 0;
};

}  // namespace lipsync::server
