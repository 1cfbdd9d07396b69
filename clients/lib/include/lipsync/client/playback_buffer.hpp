// PlaybackBuffer: plays a stream of animation frames in sync with an audio
// clock. Pure data structure: no gRPC, no threads, no clocks of its own; the
// caller passes every clock reading in.
//
// Frames (utterance time t_us + one value per channel) are pushed as they
// arrive. The buffer is anchored to a media clock: utterance time 0 plays at
// clock reading `utterance_zero_us`, so a sample asked for at clock reading c
// shows utterance time u = c − utterance_zero_us, interpolated linearly between
// the two frames around u.
//
//   - underrun: u lies beyond the newest frame and more frames are expected;
//     the newest frame is held and the sample is counted as an underrun.
//   - drift: how far the frame timeline is from the audio clock. Every sample
//     reports lead_us = newest frame time − u (positive: frames buffered ahead;
//     negative: the stream is that far behind the audio); every push with an
//     arrival time records lateness = arrival − (utterance_zero_us + t_us).
//   - never backwards: a sample earlier than the previous one is clamped to
//     the previous one (and counted), so a clock that steps back never makes
//     the mouth replay. Samples taken before any frame arrived showed nothing
//     and do not count as "previous".
//   - bounded memory: frames older than the one at or before the last sample
//     are dropped, and at most `capacity_frames` frames are held (the oldest
//     goes first, counted as dropped).
//   - playout offset: the buffer may play later than the anchor says, by
//     playout_offset_us, so that frames that can only leave the server after
//     their lookahead arrive before they are due. It is picked from what the
//     server says (the header's release delay: the lookahead's worst wait on
//     read speech; each batch's release lag: how far behind the producer's
//     newest phoneme it left): the producer's input clock is estimated from
//     each batch (arrival − t − lag, the earliest such reading), and the offset
//     is whatever makes  input clock + max(release delay, largest lag seen) +
//     margin  no later than the play time. With a producer whose playout delay
//     already covers that (lipsync stream's default), the offset stays 0 and the
//     frames play exactly on the media clock.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <span>

namespace lipsync::client {

enum class SampleState {
  no_frames,     ///< nothing received yet; `out` is left as it was
  before_first,  ///< u is before the first frame: the first frame is held
  playing,       ///< u lies within the frames: interpolated
  underrun,      ///< u is past the newest frame and more are expected: the newest is held
  ended,         ///< u is past the last frame of a finished stream: the last is held
};

struct PlaybackSample {
  SampleState state = SampleState::no_frames;
  std::int64_t utterance_us = 0;  ///< utterance time actually sampled (after clamping), µs
  std::int64_t lead_us = 0;       ///< newest frame time − utterance_us, µs (0 with no frames)
  bool clamped = false;           ///< the requested time was before the previous sample's
};

struct PlaybackStats {
  std::uint64_t frames_pushed = 0;    ///< frames accepted
  std::uint64_t frames_rejected = 0;  ///< not after the newest frame, or the wrong number of values
  std::uint64_t frames_dropped = 0;   ///< pushed out unsampled by the capacity limit
  std::uint64_t samples = 0;
  std::uint64_t underruns = 0;                   ///< samples in state underrun
  std::uint64_t clamped_samples = 0;             ///< samples that asked to go backwards
  std::int64_t max_behind_us = 0;                ///< largest −lead_us over underrun samples, µs
  std::optional<std::int64_t> min_lead_us;       ///< smallest lead_us over playing samples, µs
  std::optional<std::int64_t> last_lateness_us;  ///< arrival − play time of the newest timed push, µs
  std::optional<std::int64_t> max_lateness_us;   ///< largest such lateness, µs
  std::int64_t max_release_lag_us = 0;           ///< largest release lag a batch reported, µs
};

class PlaybackBuffer {
 public:
  static constexpr std::size_t kDefaultCapacityFrames = 1 << 14;
  /// Network and scheduling allowance on top of the server's release delay, µs.
  static constexpr std::int64_t kDefaultReleaseMarginUs = 100'000;

  /// `channel_count` values per frame (> 0); at most `capacity_frames` (> 1) frames held.
  /// Throws std::invalid_argument otherwise.
  explicit PlaybackBuffer(std::size_t channel_count, std::size_t capacity_frames = kDefaultCapacityFrames);

  /// Utterance time 0 plays at clock reading `utterance_zero_us` (µs on the caller's clock).
  void anchor(std::int64_t utterance_zero_us) { utterance_zero_us_ = utterance_zero_us; }
  bool anchored() const { return utterance_zero_us_.has_value(); }
  std::int64_t utterance_zero_us() const { return utterance_zero_us_.value_or(0); }

  /// Adds a frame at utterance time `t_us`. Returns false (and counts it rejected)
  /// when t_us is not after the newest frame or `values` has the wrong size.
  bool push(std::int64_t t_us, std::span<const float> values);
  /// Same, and records how late the frame arrived for its play time when anchored:
  /// lateness = arrival_clock_us − (utterance_zero_us + playout_offset_us + t_us).
  bool push(std::int64_t t_us, std::span<const float> values, std::int64_t arrival_clock_us);

  /// How long after the producer's input a frame may leave the server (the
  /// header's release_delay_us, µs; 0: the server does not say, no adaptation).
  /// `margin_us` is added for the network and scheduling.
  void expect_release_delay(std::int64_t release_delay_us, std::int64_t margin_us = kDefaultReleaseMarginUs);
  /// A batch whose first frame is at `first_t_us` arrived at `arrival_clock_us`,
  /// `release_lag_us` behind the producer's newest phoneme: raises or lowers the
  /// playout offset (see the top of this file). Call it before pushing the
  /// batch's frames. No effect before anchor() or without a release delay.
  void note_batch(std::int64_t first_t_us, std::int64_t release_lag_us, std::int64_t arrival_clock_us);
  /// How much later than the anchor frames play, µs (≥ 0).
  std::int64_t playout_offset_us() const { return playout_offset_us_; }

  /// No more frames will come: sampling past the last frame is `ended`, not an underrun.
  void finish() { finished_ = true; }
  bool finished() const { return finished_; }

  /// The frame for clock reading `clock_us` (requires anchored(); utterance time 0
  /// otherwise), i.e. utterance time clock_us − utterance_zero_us − playout_offset_us,
  /// written to `out` (channel_count values).
  PlaybackSample sample(std::int64_t clock_us, std::span<float> out);
  /// The frame for utterance time `utterance_us`, written to `out`.
  PlaybackSample sample_utterance(std::int64_t utterance_us, std::span<float> out);

  std::size_t channel_count() const { return channel_count_; }
  std::size_t held_frames() const { return times_us_.size(); }
  std::optional<std::int64_t> newest_frame_us() const;
  const PlaybackStats& stats() const { return stats_; }

 private:
  void drop_front();

  std::size_t channel_count_;
  std::size_t capacity_frames_;
  std::optional<std::int64_t> utterance_zero_us_;
  std::deque<std::int64_t> times_us_;
  std::deque<float> values_;  // held_frames() × channel_count_, frame-major
  std::optional<std::int64_t> last_sample_us_;
  std::int64_t release_delay_us_ = 0;
  std::int64_t release_margin_us_ = 0;
  std::optional<std::int64_t> input_zero_us_;  // earliest estimate of the producer's utterance-0 clock reading
  std::int64_t playout_offset_us_ = 0;
  bool finished_ = false;
  PlaybackStats stats_;
};

}  // namespace lipsync::client
