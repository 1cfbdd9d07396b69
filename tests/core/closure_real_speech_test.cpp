// Closures on real TTS timings (tests/data/closures: Festival and flite, flite also at 1.4x speed),
// measured where engines look: every bilabial and labiodental key frame, in the channels (within
// 5 % of the closure's targets) and in ARKit (a sealed mouth: mouthClose ≥ jawOpen − 0.02 with
// little funnel or pucker for /p b m/; the lower lip tucked under raised upper teeth for /f v/),
// at 24 to 120 frames/s, with key frames and with --fixed-rate.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "../support/closure_frames.hpp"
#include "lipsync/renderer.hpp"

namespace lipsync {
namespace {

using testing::closure_error;
using testing::closure_frames;
using testing::ClosurePlace;
using testing::kClosureTolerance;

const ArticulationModel& model() { return ArticulationModel::builtin(); }

std::size_t arkit(std::string_view name) {
  return static_cast<std::size_t>(std::find(kArkitNames.begin(), kArkitNames.end(), name) - kArkitNames.begin());
}

struct Tally {
  std::size_t bilabial = 0, labiodental = 0;
  double worst_channel_error = 0;
  double worst_seal = 1;  // smallest mouthClose − jawOpen at a bilabial frame
};

void check(const testing::TimedUtterance& utterance, const RenderOptions& options, Tally& tally) {
  const Track track = render_track(model(), utterance.segments, options);
  std::vector<float> shapes(kArkitNames.size());
  const std::string where =
      utterance.name + " at " + std::to_string(options.fps) + " fps" + (options.fixed_rate ? " fixed rate" : "");
  for (const auto& closure : closure_frames(model(), utterance.segments, track)) {
    const std::int64_t t_us = track.t_us[closure.frame];
    std::string channel;
    const double error = closure_error(model(), utterance.segments, track, closure, &channel);
    tally.worst_channel_error = std::max(tally.worst_channel_error, error);
    EXPECT_LE(error, kClosureTolerance) << where << ": /" << closure.phoneme << "/ at " << t_us << " µs, " << channel
                                        << " off by " << 100 * error << " %";
    model().retarget_to_arkit(track.frame_values(closure.frame), shapes);
    const float jaw_open = shapes[arkit("jawOpen")];
    if (closure.place == ClosurePlace::bilabial) {
      ++tally.bilabial;
      const float seal = shapes[arkit("mouthClose")] - jaw_open;
      tally.worst_seal = std::min<double>(tally.worst_seal, seal);
      EXPECT_GE(seal, -0.02F) << where << ": /" << closure.phoneme << "/ at " << t_us << " µs: mouthClose "
                              << shapes[arkit("mouthClose")] << ", jawOpen " << jaw_open;
      EXPECT_LE(shapes[arkit("mouthFunnel")], 0.1F) << where << ": /" << closure.phoneme << "/ at " << t_us << " µs";
      EXPECT_LE(shapes[arkit("mouthPucker")], 0.1F) << where << ": /" << closure.phoneme << "/ at " << t_us << " µs";
    } else {
      ++tally.labiodental;
      EXPECT_GE(shapes[arkit("mouthRollLower")], 0.3F) << where << ": /" << closure.phoneme << "/ at " << t_us << " µs";
      for (const char* side : {"mouthUpperUpLeft", "mouthUpperUpRight"}) {
        EXPECT_GE(shapes[arkit(side)], 0.2F) << where << ": /" << closure.phoneme << "/ at " << t_us << " µs, " << side;
      }
      EXPECT_LE(jaw_open, 0.15F) << where << ": /" << closure.phoneme << "/ at " << t_us << " µs";
    }
  }
}

TEST(RealSpeechClosures, EveryBilabialAndLabiodentalKeyFrameIsClosedInChannelsAndArkit) {
  const auto corpus = testing::load_closure_corpus(LIPSYNC_TEST_DATA_DIR, model());
  ASSERT_EQ(corpus.size(), 30U);
  for (const int fps : {24, 30, 60, 120}) {
    Tally tally;
    for (const auto& utterance : corpus) check(utterance, {.fps = fps}, tally);
    std::printf(
        "[ measured ] %d fps: %zu bilabial and %zu labiodental key frames; worst closing channel %.2f %% "
        "off; worst mouthClose - jawOpen %.3f\n",
        fps, tally.bilabial, tally.labiodental, 100 * tally.worst_channel_error, tally.worst_seal);
    EXPECT_GE(tally.bilabial, 90U);
    EXPECT_GE(tally.labiodental, 36U);
  }
}

TEST(RealSpeechClosures, EveryFixedRateFrameInsideAClosureIsClosed) {
  const auto corpus = testing::load_closure_corpus(LIPSYNC_TEST_DATA_DIR, model());
  for (const int fps : {24, 60, 120}) {
    Tally tally;
    for (const auto& utterance : corpus) check(utterance, {.fps = fps, .fixed_rate = true}, tally);
    EXPECT_GT(tally.bilabial + tally.labiodental, 10U) << fps << " fps";
  }
}

}  // namespace
}  // namespace lipsync
