// The transport's memory quota (a grpc::ResourceQuota over every connection's buffers and every
// call's arena), sized from the limits and following the calls in progress.
//
// gRPC 1.51 reads a message whole before it checks it against --max-message-bytes (the transport
// opens the stream's window to the length the message announces), so without a quota a 100 MB
// message costs 100 MB. The quota is what ends such a message early (RST_STREAM
// ENHANCE_YOUR_CALM, RESOURCE_EXHAUSTED at the client) once the buffers reach it. A fixed quota
// small enough for that refuses legitimate calls when many are open (each holds a few KB of
// arena and buffers: 10,000 streams need about 48 MiB), so by default the quota is
//     kMessages × max_message_bytes + kSlackBytes + kPerCallBytes × (calls in progress, rounded up
//     to kStepCalls, + kHeadroomCalls)
// and is resized as calls start and end (only when the rounded count changes): an idle server
// lets one message cost about 20 MB, a server with 10,000 open streams about 100 MB.
// --transport-memory-bytes N fixes the quota at N instead (0: none).
#pragma once

#include <grpcpp/resource_quota.h>

#include <atomic>
#include <cstddef>
#include <mutex>

namespace lipsync::server {

class TransportQuota {
 public:
  static constexpr std::size_t kMessages = 2;
  static constexpr std::size_t kSlackBytes = std::size_t{4} << 20;
  static constexpr std::size_t kPerCallBytes = std::size_t{8} << 10;
  static constexpr std::size_t kStepCalls = 256;
  static constexpr std::size_t kHeadroomCalls = 1024;

  /// A quota of `base_bytes`, plus kPerCallBytes per call (rounded, with headroom) when `following`.
  TransportQuota(std::size_t base_bytes, bool following);
  /// The base of the default quota for `max_message_bytes`.
  static std::size_t base_for(std::size_t max_message_bytes) { return kMessages * max_message_bytes + kSlackBytes; }

  grpc::ResourceQuota& resource_quota() { return quota_; }
  /// The size for `calls` calls in progress (a fixed quota: its size).
  std::size_t size_for(std::size_t calls) const;
  /// Resizes to size_for(calls) if it differs from the current size. Thread-safe.
  void follow(std::size_t calls);
  /// The current size, bytes.
  std::size_t size_bytes() const;

 private:
  grpc::ResourceQuota quota_{"lipsyncd"};
  const std::size_t base_bytes_;
  const bool following_;
  std::mutex resize_mutex_;                 // resizes in order
  std::atomic<std::size_t> size_bytes_{0};  // read without the lock: most calls change nothing
};

}  // namespace lipsync::server
