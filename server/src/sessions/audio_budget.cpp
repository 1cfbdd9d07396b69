#include "sessions/audio_budget.hpp"

namespace lipsync::server {

bool AudioBudget::try_reserve(std::size_t bytes) {
  std::lock_guard lock(mutex_);
  if (bytes > limit_bytes_ - held_bytes_) return false;
  held_bytes_ += bytes;
  return true;
}

void AudioBudget::release(std::size_t bytes) noexcept {
  std::lock_guard lock(mutex_);
  held_bytes_ -= bytes < held_bytes_ ? bytes : held_bytes_;
}

std::shared_ptr<const std::string> AudioBudget::keep(std::string wav) {
  const std::size_t bytes = wav.size();
  return {new const std::string(std::move(wav)), [budget = shared_from_this(), bytes](const std::string* kept) {
            delete kept;
            budget->release(bytes);
          }};
}

std::size_t AudioBudget::held_bytes() const {
  std::lock_guard lock(mutex_);
  return held_bytes_;
}

}  // namespace lipsync::server
