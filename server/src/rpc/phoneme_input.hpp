// Phonemes from the wire into segments, one at a time, under the server's
// limits. Animate and Render both feed their phonemes through a PhonemeInput:
// each goes through the core's SegmentBuilder (source "phoneme stream", line =
// the 1-based phoneme index), so a bad phoneme is reported with its index
// whatever the chunking, and the utterance is held to --max-phonemes and
// --max-utterance-ms (RESOURCE_EXHAUSTED naming the flag).
#pragma once

#include <grpcpp/support/status.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "lipsync/segment.hpp"
#include "lipsync/server/config.hpp"
#include "lipsync/v1/lipsync.pb.h"
#include "rpc/plan.hpp"

namespace lipsync::server {

/// The source name bad phonemes are reported under.
inline constexpr const char* kStreamSource = "phoneme stream";

/// RESOURCE_EXHAUSTED: more than `limit` phonemes (--max-phonemes).
grpc::Status too_many_phonemes(std::size_t limit);

class PhonemeInput {
 public:
  PhonemeInput(const Plan& plan, const ServerConfig& config);

  /// Counts in the next phoneme and appends the segments it yields to `out`;
  /// INVALID_ARGUMENT for bad timing or an unknown label, RESOURCE_EXHAUSTED
  /// beyond the limits.
  grpc::Status push(const v1::Phoneme& phoneme, std::vector<Segment>& out);

  /// Phonemes counted so far (including one that was refused).
  std::size_t count() const { return count_; }
  /// End of the last phoneme accepted (0 before the first).
  std::int64_t end_us() const { return builder_.end_us(); }
  /// Start of the last phoneme accepted (0 before the first): with phonemes sent
  /// as they are spoken, how far the producer's utterance clock has got.
  std::int64_t newest_start_us() const { return newest_start_us_; }

 private:
  const ServerConfig& config_;
  SegmentBuilder builder_;
  std::size_t count_ = 0;
  std::int64_t newest_start_us_ = 0;
};

}  // namespace lipsync::server
