#include "lipsync/renderer.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "lipsync/phone_set.hpp"
#include "lipsync/synthetic.hpp"
#include "random_segments.hpp"
#include "test_model.hpp"

namespace lipsync {
namespace {

using testing::test_model;

Track stream(const ArticulationModel& model, const std::vector<Segment>& segments, RenderOptions options) {
  StreamingRenderer renderer(model, options);
  Track track;
  track.channel_count = model.channel_count();
  track.fps = options.fps;
  for (const Segment& segment : segments) renderer.push(segment, track);
  renderer.finish(track);
  return track;
}

void expect_identical(const Track& actual, const Track& expected) {
  ASSERT_EQ(actual.frame_count(), expected.frame_count());
  EXPECT_EQ(actual.t_us, expected.t_us);
  EXPECT_EQ(actual.kinds, expected.kinds);
  EXPECT_EQ(actual.articulation.size(), actual.frame_count());
  EXPECT_EQ(actual.articulation, expected.articulation);  // closures and pauses too (visemes read them)
  // Bitwise: memcmp-equal floats, not "near".
  ASSERT_EQ(actual.values.size(), expected.values.size());
  EXPECT_EQ(0, std::memcmp(actual.values.data(), expected.values.data(), actual.values.size() * sizeof(float)));
}

TEST(StreamingRenderer, EqualsTheOfflineRenderValueForValue) {
  for (std::uint64_t seed = 1; seed <= 30; ++seed) {
    const auto segments = testing::random_segments(test_model(), 1 + seed * 7, seed);
    for (int fps : {1, 20, 30, 240}) {
      SCOPED_TRACE("seed " + std::to_string(seed) + ", fps " + std::to_string(fps));
      expect_identical(stream(test_model(), segments, {.fps = fps}),
                       render_track(test_model(), segments, {.fps = fps}));
    }
  }
}

TEST(StreamingRenderer, EqualsTheOfflineRenderForEveryLookahead) {
  const auto segments = testing::random_segments(test_model(), 300, 42);
  for (int lookahead = 0; lookahead <= 7; ++lookahead) {
    SCOPED_TRACE("lookahead " + std::to_string(lookahead));
    expect_identical(stream(test_model(), segments, {.lookahead = lookahead}),
                     render_track(test_model(), segments, {.lookahead = lookahead}));
  }
}

TEST(StreamingRenderer, ChunkedPhonemeInputGivesTheSameTrackAsAWholeFile) {
  // Built-in model and phone set, synthetic ARPAbet speech, random chunk sizes.
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const auto intervals = synthesize_utterance({.phonemes = 400, .seed = seed, .leave_gaps = seed % 2 == 0});
    const Track offline = render_track(model, build_segments({"synthetic", "", intervals}, model, arpabet));

    std::mt19937_64 random(seed);
    SegmentBuilder builder(model, arpabet, "stream");
    StreamingRenderer renderer(model);
    Track streamed;
    streamed.channel_count = model.channel_count();
    std::vector<Segment> chunk_segments;
    for (std::size_t i = 0; i < intervals.size();) {
      const std::size_t chunk = 1 + random() % 12;
      for (std::size_t end = std::min(intervals.size(), i + chunk); i < end; ++i)
        builder.push(intervals[i], chunk_segments);
      for (const Segment& segment : chunk_segments) renderer.push(segment, streamed);
      chunk_segments.clear();
    }
    renderer.finish(streamed);
    SCOPED_TRACE("seed " + std::to_string(seed));
    expect_identical(streamed, offline);
  }
}

TEST(StreamingRenderer, EmitsAFrameOnceSevenSegmentsAfterItAreKnown) {
  const auto segments = testing::make_segments(test_model(), {{"aa", 0.0, 0.1},
                                                              {"iy", 0.1, 0.2},
                                                              {"s", 0.2, 0.3},
                                                              {"aa", 0.3, 0.4},
                                                              {"t", 0.4, 0.5},
                                                              {"aa", 0.5, 0.6},
                                                              {"iy", 0.6, 0.7},
                                                              {"s", 0.7, 0.8},
                                                              {"aa", 0.8, 0.9}});
  StreamingRenderer renderer(test_model(), {.fps = 10});
  Track track;
  track.channel_count = test_model().channel_count();
  std::vector<std::size_t> frames_after_push;
  for (const Segment& segment : segments) {
    renderer.push(segment, track);
    frames_after_push.push_back(track.frame_count());
  }
  // One frame per 100 ms segment; the frame in segment k leaves with segment k+7.
  EXPECT_THAT(frames_after_push, ::testing::ElementsAre(0, 0, 0, 0, 0, 0, 0, 1, 2));
  renderer.finish(track);
  EXPECT_EQ(track.frame_count(), 9U);
}

TEST(StreamingRenderer, LookaheadZeroEmitsAsSoonAsTheSegmentArrives) {
  const auto segments = testing::make_segments(test_model(), {{"aa", 0.0, 0.1}, {"iy", 0.1, 0.2}, {"s", 0.2, 0.3}});
  StreamingRenderer renderer(test_model(), {.fps = 10, .lookahead = 0});
  Track track;
  track.channel_count = test_model().channel_count();
  renderer.push(segments[0], track);
  EXPECT_EQ(track.frame_count(), 1U);
  renderer.push(segments[1], track);
  EXPECT_EQ(track.frame_count(), 2U);
}

TEST(StreamingRenderer, MemoryStaysBoundedByTheWindow) {
  StreamingRenderer renderer(test_model(), {.fps = 240});
  Track track;
  track.channel_count = test_model().channel_count();
  std::size_t most_segments = 0;
  std::size_t most_pending = 0;
  for (const Segment& segment : testing::random_segments(test_model(), 20'000, 9)) {
    renderer.push(segment, track);
    most_segments = std::max(most_segments, renderer.held_segments());
    most_pending = std::max(most_pending, renderer.pending_frames());
    track.clear();  // a consumer that ships frames as they come
  }
  EXPECT_LE(most_segments, 2U * kWindowRadius + 1);
  EXPECT_LE(most_pending, 8U * 400 * 240 / 1000 + 8);  // 8 segments of at most 400 ms at 240 fps
}

TEST(RenderTrack, RejectsLookaheadOutsideZeroToSeven) {
  const auto segments = testing::make_segments(test_model(), {{"aa", 0.0, 0.1}});
  EXPECT_THROW(render_track(test_model(), segments, {.lookahead = 8}), std::invalid_argument);
  EXPECT_THROW(render_track(test_model(), segments, {.lookahead = -1}), std::invalid_argument);
}

TEST(RenderTrack, EveryValueStaysInItsChannelRangeAndFinite) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  const auto intervals = synthesize_utterance({.phonemes = 3000, .seed = 11});
  const Track track = render_track(model, build_segments({"synthetic", "", intervals}, model, arpabet), {.fps = 60});
  for (std::size_t f = 0; f < track.frame_count(); ++f) {
    const auto values = track.frame_values(f);
    for (std::size_t c = 0; c < values.size(); ++c) {
      ASSERT_TRUE(std::isfinite(values[c]));
      ASSERT_GE(values[c], static_cast<float>(model.channels()[c].min)) << model.channels()[c].name;
      ASSERT_LE(values[c], static_cast<float>(model.channels()[c].max)) << model.channels()[c].name;
    }
  }
}

}  // namespace
}  // namespace lipsync
