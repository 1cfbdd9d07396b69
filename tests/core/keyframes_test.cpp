#include "lipsync/keyframes.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "test_model.hpp"

namespace lipsync {
namespace {

using testing::make_segments;
using testing::test_model;

struct Timed {
  std::int64_t t_us;
  FrameKind kind;
  bool operator==(const Timed&) const = default;
};

void PrintTo(const Timed& frame, std::ostream* os) { *os << frame.t_us << " µs " << to_string(frame.kind); }

std::vector<Timed> schedule(const std::vector<Segment>& segments, ScheduleOptions options) {
  FrameScheduler scheduler(test_model(), options);
  std::vector<ScheduledFrame> frames;
  for (std::size_t i = 0; i < segments.size(); ++i) scheduler.add_segment(segments[i], i, frames);
  scheduler.finish(frames);
  std::vector<Timed> timed;
  for (const auto& frame : frames) timed.push_back({frame.t_us, frame.kind});
  return timed;
}

std::vector<Timed> uniform_from(std::int64_t start_us, std::int64_t step_us, std::int64_t before_us) {
  std::vector<Timed> frames;
  for (std::int64_t t = start_us; t < before_us; t += step_us) frames.push_back({t, FrameKind::uniform});
  return frames;
}

TEST(FrameScheduler, ReproducesThePaperFigure5Timeline) {
  // 'speech' /s pcl p i tcl tʃ/ at 20 fps: uniform samples, a key frame at
  // the closure start (0.359), one at its end (0.423), then every 0.05 s.
  const auto segments = make_segments(test_model(), {{"sil", 0.0, 0.2},
                                                     {"s", 0.2, 0.359},
                                                     {"pcl", 0.359, 0.423},
                                                     {"p", 0.423, 0.47},
                                                     {"iy", 0.47, 0.6},
                                                     {"t", 0.6, 0.66},
                                                     {"ch", 0.66, 0.8},
                                                     {"sil", 0.8, 1.0}});
  std::vector<Timed> expected = uniform_from(0, 50'000, 359'000);
  expected.push_back({359'000, FrameKind::closure_start});
  expected.push_back({423'000, FrameKind::closure_end});
  for (const Timed& frame : uniform_from(473'000, 50'000, 1'000'000)) expected.push_back(frame);
  EXPECT_THAT(schedule(segments, {.fps = 20}), ::testing::ElementsAreArray(expected));
}

TEST(FrameScheduler, GridTimesAreExactMicrosecondsWithoutDrift) {
  const auto segments = make_segments(test_model(), {{"aa", 0.0, 3600.0}});
  const auto frames = schedule(segments, {.fps = 30});
  ASSERT_EQ(frames.size(), 108'000U);
  EXPECT_EQ(frames[1].t_us, 33'333);
  EXPECT_EQ(frames[2].t_us, 66'667);
  EXPECT_EQ(frames[3].t_us, 100'000);
  EXPECT_EQ(frames[107'999].t_us, 3'599'966'667);
}

TEST(FrameScheduler, ClosureHasKeyFramesAtBothEndsAndNoUniformFramesInside) {
  const auto segments = make_segments(test_model(), {{"aa", 0.0, 0.11}, {"m", 0.11, 0.31}, {"aa", 0.31, 0.4}});
  EXPECT_THAT(schedule(segments, {.fps = 30}),
              ::testing::ElementsAre(Timed{0, FrameKind::uniform}, Timed{33'333, FrameKind::uniform},
                                     Timed{66'667, FrameKind::uniform}, Timed{100'000, FrameKind::uniform},
                                     Timed{110'000, FrameKind::closure_start}, Timed{310'000, FrameKind::closure_end},
                                     Timed{343'333, FrameKind::uniform}, Timed{376'667, FrameKind::uniform}));
}

TEST(FrameScheduler, AdjacentClosuresShareOneKeyFrame) {
  const auto segments = make_segments(test_model(), {{"m", 0.0, 0.1}, {"pcl", 0.1, 0.15}, {"p", 0.15, 0.2}});
  EXPECT_THAT(schedule(segments, {.fps = 10}),
              ::testing::ElementsAre(Timed{0, FrameKind::closure_start}, Timed{100'000, FrameKind::closure_start},
                                     Timed{150'000, FrameKind::closure_end}));
}

TEST(FrameScheduler, ClosureEndingTheUtteranceGetsItsEndFrame) {
  const auto segments = make_segments(test_model(), {{"aa", 0.0, 0.1}, {"m", 0.1, 0.2}});
  EXPECT_THAT(schedule(segments, {.fps = 20}),
              ::testing::ElementsAre(Timed{0, FrameKind::uniform}, Timed{50'000, FrameKind::uniform},
                                     Timed{100'000, FrameKind::closure_start}, Timed{200'000, FrameKind::closure_end}));
}

TEST(FrameScheduler, ShortSegmentGetsAFrameAtItsPeakWithoutMovingTheGrid) {
  // 't' (10 ms) falls between two frames at 20 fps: one frame at its centre.
  const auto segments = make_segments(test_model(), {{"aa", 0.0, 0.06}, {"t", 0.06, 0.07}, {"aa", 0.07, 0.2}});
  EXPECT_THAT(schedule(segments, {.fps = 20}),
              ::testing::ElementsAre(Timed{0, FrameKind::uniform}, Timed{50'000, FrameKind::uniform},
                                     Timed{65'000, FrameKind::short_segment}, Timed{100'000, FrameKind::uniform},
                                     Timed{150'000, FrameKind::uniform}));
}

TEST(FrameScheduler, ShortSegmentPeakHonoursThePeakOffsetAndIsClampedIntoTheSegment) {
  // 'sharp' has t_off = 10 ms: its peak sits 10 ms before the centre.
  auto segments = make_segments(test_model(), {{"aa", 0.0, 0.06}, {"sharp", 0.06, 0.09}, {"aa", 0.09, 0.2}});
  EXPECT_EQ(schedule(segments, {.fps = 20})[2], (Timed{65'000, FrameKind::short_segment}));
  segments = make_segments(test_model(), {{"aa", 0.0, 0.06}, {"sharp", 0.06, 0.065}, {"aa", 0.065, 0.2}});
  EXPECT_EQ(schedule(segments, {.fps = 20})[2], (Timed{60'000, FrameKind::short_segment}));
}

TEST(FrameScheduler, FixedRateModeUsesOnlyTheGrid) {
  const auto segments =
      make_segments(test_model(), {{"aa", 0.0, 0.11}, {"m", 0.11, 0.31}, {"t", 0.31, 0.32}, {"aa", 0.32, 0.4}});
  EXPECT_THAT(schedule(segments, {.fps = 10, .fixed_rate = true}),
              ::testing::ElementsAreArray(uniform_from(0, 100'000, 400'000)));
}

TEST(FrameScheduler, RejectsFrameRatesOutsideOneTo240) {
  EXPECT_THROW(FrameScheduler(test_model(), {.fps = 0}), std::invalid_argument);
  EXPECT_THROW(FrameScheduler(test_model(), {.fps = 241}), std::invalid_argument);
  EXPECT_NO_THROW(FrameScheduler(test_model(), {.fps = 240}));
}

}  // namespace
}  // namespace lipsync
