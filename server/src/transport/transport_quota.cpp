// The transport quota that follows the calls (transport_quota.hpp).
#include "transport_quota.hpp"

namespace lipsync::server {

TransportQuota::TransportQuota(std::size_t base_bytes, bool following)
    : base_bytes_(base_bytes), following_(following) {
  size_bytes_ = size_for(0);
  quota_.Resize(size_bytes_);
}

std::size_t TransportQuota::size_for(std::size_t calls) const {
  if (!following_) return base_bytes_;
  const std::size_t rounded = (calls + kStepCalls - 1) / kStepCalls * kStepCalls;
  return base_bytes_ + kPerCallBytes * (rounded + kHeadroomCalls);
}

void TransportQuota::follow(std::size_t calls) {
  if (!following_) return;
  if (size_for(calls) == size_bytes_.load(std::memory_order_relaxed)) return;
  std::lock_guard lock(resize_mutex_);
  // The count may have moved on while this thread waited: size for the calls now.
  const std::size_t wanted = size_for(calls);
  if (wanted == size_bytes_.load()) return;
  size_bytes_ = wanted;
  quota_.Resize(wanted);
}

std::size_t TransportQuota::size_bytes() const { return size_bytes_.load(); }

}  // namespace lipsync::server
