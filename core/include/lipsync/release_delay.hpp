// How long a streamed frame waits for its lookahead on read speech.
//
// A frame of segment k leaves the streaming renderer once segments k..k+L are
// known (L = lookahead). When a producer sends each phoneme as it is spoken,
// that is when the phoneme of segment k+L arrives, so the wait is set by the
// durations of the phonemes that follow, not by the engine's speed. The server
// states the bound below in its track header (TrackHeader.release_delay_us) and
// `lipsync stream` uses it for its default playout delay, so that a player that
// plays on the producer's media clock sees no late frame on read speech.
//
// The bounds are the largest waits measured by tests/bench/lookahead_error on
// the first 20 Harvard sentences read by flite (the larger of the "max wait"
// columns of docs/streaming.md at 30 and 60 fps), plus a 20 % margin for slower
// speakers, rounded up to 10 ms. A pause longer than the window in the middle of
// speech waits longer; the server's per-batch release lag tells players so.
#pragma once

#include <array>
#include <cstdint>

#include "lipsync/setting_ranges.hpp"

namespace lipsync {

/// Index: lookahead 0..7 (kLookaheadSetting). µs.
inline constexpr std::array<std::int64_t, 8> kReadSpeechReleaseDelayUs = {
    // lookahead:  0        1        2        3        4          5          6          7
    350'000, 670'000, 770'000, 930'000, 1'010'000, 1'210'000, 1'390'000, 1'530'000,
};

/// The release delay for `lookahead`, clamped to the setting's range, µs.
constexpr std::int64_t read_speech_release_delay_us(std::int64_t lookahead) {
  if (lookahead < kLookaheadSetting.min) lookahead = kLookaheadSetting.min;
  if (lookahead > kLookaheadSetting.max) lookahead = kLookaheadSetting.max;
  return kReadSpeechReleaseDelayUs[static_cast<std::size_t>(lookahead)];
}

}  // namespace lipsync
