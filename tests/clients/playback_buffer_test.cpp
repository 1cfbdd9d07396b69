// PlaybackBuffer: interpolation between the frames around the sampled time,
// anchoring to a media clock, underruns, drift, never going backwards and
// bounded memory.
#include "lipsync/client/playback_buffer.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <random>
#include <vector>

namespace lipsync::client {
namespace {

using ::testing::ElementsAre;
using ::testing::FloatEq;
using ::testing::Pointwise;

std::vector<float> sample_values(PlaybackBuffer& buffer, std::int64_t utterance_us, PlaybackSample* result = nullptr) {
  std::vector<float> out(buffer.channel_count(), -1.0F);
  const PlaybackSample sample = buffer.sample_utterance(utterance_us, out);
  if (result != nullptr) *result = sample;
  return out;
}

PlaybackBuffer two_channel_ramp() {
  PlaybackBuffer buffer(2);
  buffer.push(0, std::array{0.0F, 1.0F});
  buffer.push(100, std::array{1.0F, 0.0F});
  buffer.push(300, std::array{3.0F, 0.0F});
  return buffer;
}

TEST(PlaybackBuffer, InterpolatesLinearlyBetweenTheFramesAroundTheTime) {
  PlaybackBuffer buffer = two_channel_ramp();
  EXPECT_THAT(sample_values(buffer, 0), ElementsAre(FloatEq(0.0F), FloatEq(1.0F)));
  EXPECT_THAT(sample_values(buffer, 25), ElementsAre(FloatEq(0.25F), FloatEq(0.75F)));
  EXPECT_THAT(sample_values(buffer, 100), ElementsAre(FloatEq(1.0F), FloatEq(0.0F)));
  EXPECT_THAT(sample_values(buffer, 200), ElementsAre(FloatEq(2.0F), FloatEq(0.0F)));
  PlaybackSample sample;
  EXPECT_THAT(sample_values(buffer, 300, &sample), ElementsAre(FloatEq(3.0F), FloatEq(0.0F)));
  EXPECT_EQ(sample.state, SampleState::playing);
  EXPECT_EQ(sample.lead_us, 0);
}

TEST(PlaybackBuffer, HoldsTheFirstFrameBeforeIt) {
  PlaybackBuffer buffer(1);
  buffer.push(1000, std::array{0.5F});
  PlaybackSample sample;
  EXPECT_THAT(sample_values(buffer, 10, &sample), ElementsAre(FloatEq(0.5F)));
  EXPECT_EQ(sample.state, SampleState::before_first);
  EXPECT_EQ(buffer.stats().underruns, 0U);
}

TEST(PlaybackBuffer, LeavesTheOutputAloneWithNoFrames) {
  PlaybackBuffer buffer(1);
  PlaybackSample sample;
  EXPECT_THAT(sample_values(buffer, 10, &sample), ElementsAre(FloatEq(-1.0F)));
  EXPECT_EQ(sample.state, SampleState::no_frames);
  EXPECT_EQ(buffer.stats().underruns, 0U);
}

TEST(PlaybackBuffer, SampleUsesTheMediaClockAnchor) {
  PlaybackBuffer buffer = two_channel_ramp();
  buffer.anchor(1'000'000);
  std::vector<float> out(2);
  const PlaybackSample sample = buffer.sample(1'000'050, out);
  EXPECT_EQ(sample.utterance_us, 50);
  EXPECT_THAT(out, ElementsAre(FloatEq(0.5F), FloatEq(0.5F)));
  EXPECT_EQ(sample.lead_us, 250);
}

TEST(PlaybackBuffer, UnderrunHoldsTheNewestFrameAndIsCounted) {
  PlaybackBuffer buffer = two_channel_ramp();
  PlaybackSample sample;
  EXPECT_THAT(sample_values(buffer, 450, &sample), ElementsAre(FloatEq(3.0F), FloatEq(0.0F)));
  EXPECT_EQ(sample.state, SampleState::underrun);
  EXPECT_EQ(sample.lead_us, -150);
  sample_values(buffer, 500);
  EXPECT_EQ(buffer.stats().underruns, 2U);
  EXPECT_EQ(buffer.stats().max_behind_us, 200);

  // Frames that arrive later play again, from the time reached.
  buffer.push(600, std::array{6.0F, 1.0F});
  EXPECT_THAT(sample_values(buffer, 550, &sample), ElementsAre(FloatEq(5.5F), FloatEq(2.5F / 3.0F)));
  EXPECT_EQ(sample.state, SampleState::playing);
}

TEST(PlaybackBuffer, PastTheEndOfAFinishedStreamIsNotAnUnderrun) {
  PlaybackBuffer buffer = two_channel_ramp();
  buffer.finish();
  PlaybackSample sample;
  EXPECT_THAT(sample_values(buffer, 1000, &sample), ElementsAre(FloatEq(3.0F), FloatEq(0.0F)));
  EXPECT_EQ(sample.state, SampleState::ended);
  EXPECT_EQ(buffer.stats().underruns, 0U);
}

TEST(PlaybackBuffer, DriftReportsTheLeadOfTheNewestFrameAndArrivalLateness) {
  PlaybackBuffer buffer(1);
  buffer.anchor(10'000);
  buffer.push(0, std::array{0.0F}, 9'000);      // 1 ms early
  buffer.push(1000, std::array{1.0F}, 13'500);  // plays at 11'000: 2.5 ms late
  buffer.push(2000, std::array{2.0F}, 12'500);  // plays at 12'000: 0.5 ms late
  EXPECT_EQ(buffer.stats().last_lateness_us, 500);
  EXPECT_EQ(buffer.stats().max_lateness_us, 2500);

  std::vector<float> out(1);
  EXPECT_EQ(buffer.sample(10'500, out).lead_us, 1500);
  EXPECT_EQ(buffer.sample(11'900, out).lead_us, 100);
  EXPECT_EQ(buffer.stats().min_lead_us, 100);
}

TEST(PlaybackBuffer, NeverGoesBackwards) {
  PlaybackBuffer buffer = two_channel_ramp();
  sample_values(buffer, 200);
  PlaybackSample sample;
  EXPECT_THAT(sample_values(buffer, 50, &sample), ElementsAre(FloatEq(2.0F), FloatEq(0.0F)));
  EXPECT_TRUE(sample.clamped);
  EXPECT_EQ(sample.utterance_us, 200);
  EXPECT_EQ(buffer.stats().clamped_samples, 1U);
  EXPECT_FALSE(sample_values(buffer, 200, &sample).empty());
  EXPECT_FALSE(sample.clamped);
}

TEST(PlaybackBuffer, RejectsFramesThatDoNotMoveForwardOrHaveTheWrongSize) {
  PlaybackBuffer buffer(2);
  EXPECT_TRUE(buffer.push(100, std::array{0.0F, 0.0F}));
  EXPECT_FALSE(buffer.push(100, std::array{0.0F, 0.0F}));
  EXPECT_FALSE(buffer.push(50, std::array{0.0F, 0.0F}));
  EXPECT_FALSE(buffer.push(200, std::array{0.0F}));
  EXPECT_EQ(buffer.stats().frames_pushed, 1U);
  EXPECT_EQ(buffer.stats().frames_rejected, 3U);
}

TEST(PlaybackBuffer, KeepsOnlyTheFrameBeforeTheLastSampleAndThoseAfter) {
  PlaybackBuffer buffer(1);
  for (int i = 0; i < 100; ++i) buffer.push(i * 1000, std::array{static_cast<float>(i)});
  EXPECT_EQ(buffer.held_frames(), 100U);
  EXPECT_THAT(sample_values(buffer, 42'500), ElementsAre(FloatEq(42.5F)));
  EXPECT_EQ(buffer.held_frames(), 58U);  // frames 42..99
  sample_values(buffer, 500'000);
  EXPECT_EQ(buffer.held_frames(), 1U);
}

TEST(PlaybackBuffer, CapacityBoundsMemoryWhenNobodySamples) {
  PlaybackBuffer buffer(3, 16);
  for (int i = 0; i < 1000; ++i) buffer.push(i, std::array{0.0F, 1.0F, 2.0F});
  EXPECT_EQ(buffer.held_frames(), 16U);
  EXPECT_EQ(buffer.stats().frames_dropped, 984U);
  EXPECT_EQ(buffer.newest_frame_us(), 999);
}

// Property: random frame timelines sampled on a jittery, occasionally
// backwards clock stay within the range of the frames around the sample,
// never go backwards, and hold memory to what is still ahead.
TEST(PlaybackBuffer, RandomStreamsInterpolateWithinNeighboursAndStayBounded) {
  std::mt19937_64 random(7);
  std::uniform_int_distribution<std::int64_t> step_us(1, 40'000);
  std::uniform_real_distribution<float> value(-1.0F, 1.0F);
  std::uniform_int_distribution<std::int64_t> jitter_us(-3'000, 20'000);
  PlaybackBuffer buffer(1);
  std::vector<std::int64_t> times;
  std::vector<float> values;
  std::int64_t t = 0;
  for (int i = 0; i < 2000; ++i) {
    t += step_us(random);
    times.push_back(t);
    values.push_back(value(random));
    ASSERT_TRUE(buffer.push(t, std::array{values.back()}));
  }
  std::int64_t clock = times.front();
  std::int64_t previous = clock;
  std::vector<float> out(1);
  while (clock < t) {
    clock += jitter_us(random);
    const PlaybackSample sample = buffer.sample_utterance(clock, out);
    ASSERT_GE(sample.utterance_us, previous);
    previous = sample.utterance_us;
    const auto after = std::upper_bound(times.begin(), times.end(), sample.utterance_us);
    ASSERT_NE(after, times.begin());
    const auto i = static_cast<std::size_t>(after - times.begin()) - 1;
    const float low = std::min(values[i], i + 1 < values.size() ? values[i + 1] : values[i]);
    const float high = std::max(values[i], i + 1 < values.size() ? values[i + 1] : values[i]);
    ASSERT_GE(out[0], low - 1e-6F) << "at " << sample.utterance_us;
    ASSERT_LE(out[0], high + 1e-6F) << "at " << sample.utterance_us;
    ASSERT_EQ(buffer.held_frames(), times.size() - i) << "at " << sample.utterance_us;
  }
  EXPECT_GT(buffer.stats().clamped_samples, 0U);
}

// Playout offset: the producer's input reaches utterance time 0 at clock 0 and
// its media clock plays utterance time 0 at 1 s; the server says frames may
// leave up to 1.5 s after the input (release delay), and the buffer allows
// 0.1 s on top.
constexpr std::int64_t kAnchorUs = 1'000'000;
constexpr std::int64_t kReleaseDelayUs = 1'500'000;
constexpr std::int64_t kMarginUs = 100'000;

PlaybackBuffer released_stream(std::int64_t anchor_us = kAnchorUs) {
  PlaybackBuffer buffer(1);
  buffer.anchor(anchor_us);
  buffer.expect_release_delay(kReleaseDelayUs, kMarginUs);
  return buffer;
}

TEST(PlaybackBuffer, PlaysLateEnoughForTheServersReleaseDelayBeforeAnyFrameIsLate) {
  PlaybackBuffer buffer = released_stream();
  // The first batch left 1.2 s after the input reached its frame (lag): with the
  // 1 s anchor it would be 0.2 s late, and later frames up to 0.5 s late.
  buffer.note_batch(0, 1'200'000, 1'200'000);
  EXPECT_EQ(buffer.playout_offset_us(), kReleaseDelayUs + kMarginUs - kAnchorUs);
  ASSERT_TRUE(buffer.push(0, std::array{0.0F}, 1'200'000));
  buffer.note_batch(33'333, 1'500'000, 1'533'333);
  ASSERT_TRUE(buffer.push(33'333, std::array{1.0F}, 1'533'333));
  EXPECT_EQ(buffer.stats().max_lateness_us, 1'533'333 - (kAnchorUs + buffer.playout_offset_us() + 33'333));
  EXPECT_LT(*buffer.stats().max_lateness_us, 0);
  std::array<float, 1> out{};
  EXPECT_EQ(buffer.sample(kAnchorUs + buffer.playout_offset_us() + 33'333, out).state, SampleState::playing);
  EXPECT_EQ(buffer.stats().underruns, 0U);
}

TEST(PlaybackBuffer, KeepsTheMediaClockWhenTheProducersDelayCoversTheReleaseDelay) {
  PlaybackBuffer buffer = released_stream(kReleaseDelayUs + 2 * kMarginUs);
  buffer.note_batch(0, 1'200'000, 1'201'000);
  EXPECT_EQ(buffer.playout_offset_us(), 0);
  std::array<float, 1> out{};
  ASSERT_TRUE(buffer.push(0, std::array{0.0F}, 1'201'000));
  EXPECT_EQ(buffer.sample(kReleaseDelayUs + 2 * kMarginUs, out).utterance_us, 0);
}

TEST(PlaybackBuffer, ALagBeyondTheReleaseDelayRaisesTheOffsetForTheFramesAfterIt) {
  PlaybackBuffer buffer = released_stream();
  buffer.note_batch(0, 500'000, 500'000);
  const std::int64_t before = buffer.playout_offset_us();
  // A pause inside the lookahead window: this batch waited 2 s for its input.
  buffer.note_batch(1'000'000, 2'000'000, 3'000'000);
  EXPECT_EQ(buffer.playout_offset_us(), 2'000'000 + kMarginUs - kAnchorUs);
  EXPECT_GT(buffer.playout_offset_us(), before);
  EXPECT_EQ(buffer.stats().max_release_lag_us, 2'000'000);
}

TEST(PlaybackBuffer, AReplayedBatchDoesNotHoldTheOffsetOnceALiveOneArrives) {
  PlaybackBuffer buffer = released_stream();
  // A late joiner: the first batches are replayed 5 s after they were released.
  buffer.note_batch(0, 1'000'000, 6'000'000);
  EXPECT_GT(buffer.playout_offset_us(), 4'000'000);
  // The first live batch arrives as it leaves the server: the input clock was at 0.
  buffer.note_batch(4'800'000, 1'000'000, 5'800'000);
  EXPECT_EQ(buffer.playout_offset_us(), kReleaseDelayUs + kMarginUs - kAnchorUs);
}

TEST(PlaybackBuffer, SamplesBeforeTheFirstFrameDoNotHoldBackALaterPlayoutOffset) {
  PlaybackBuffer buffer = released_stream();
  std::array<float, 1> out{};
  // The player ticks before anything arrived: the media clock is already at 0.4 s.
  EXPECT_EQ(buffer.sample(kAnchorUs + 400'000, out).state, SampleState::no_frames);
  buffer.note_batch(0, 1'200'000, 1'200'000);
  ASSERT_TRUE(buffer.push(0, std::array{0.5F}, 1'200'000));
  // With the offset the clock now shows utterance time −0.4 s: the first frame, held, not an underrun.
  const PlaybackSample sample = buffer.sample(1'200'000, out);
  EXPECT_EQ(sample.state, SampleState::before_first);
  EXPECT_FALSE(sample.clamped);
  EXPECT_EQ(buffer.stats().underruns, 0U);
}

TEST(PlaybackBuffer, WithoutAReleaseDelayFromTheServerTheOffsetStaysZero) {
  PlaybackBuffer buffer(1);
  buffer.anchor(kAnchorUs);
  buffer.note_batch(0, 1'200'000, 1'200'000);
  EXPECT_EQ(buffer.playout_offset_us(), 0);
  EXPECT_EQ(buffer.stats().max_release_lag_us, 1'200'000);
}

}  // namespace
}  // namespace lipsync::client
