// The live stream's renderer (lipsync/live_renderer.hpp): with every phoneme final before its
// deadline, or a guess that is the truth, the stream is the offline render bit for bit; whatever the
// guesses, frames leave once, in time order, never past their deadline, and the end of the stream
// brings every frame still due.
#include "lipsync/live_renderer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include "lipsync/coarticulation.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/synthetic.hpp"

namespace lipsync {
namespace {

struct Fixture {
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  std::shared_ptr<const CoarticulationTables> tables = std::make_shared<const CoarticulationTables>(model);

  LiveRenderer renderer() const { return LiveRenderer(tables, model, arpabet, "live", {}, {}); }
  Track empty_track() const {
    Track track;
    track.channel_count = model.channel_count();
    return track;
  }
  Track offline(const std::vector<LabeledInterval>& phonemes) const {
    LabeledUtterance utterance;
    utterance.intervals = phonemes;
    return render_track(model, build_segments(utterance, model, arpabet));
  }
};

/// Contiguous phonemes (the synthetic utterance with its gaps closed), as a recogniser gives them.
std::vector<LabeledInterval> contiguous_utterance(std::size_t phonemes, std::uint64_t seed) {
  std::vector<LabeledInterval> intervals = synthesize_utterance({.phonemes = phonemes, .seed = seed});
  for (std::size_t i = 1; i < intervals.size(); ++i) intervals[i].start_us = intervals[i - 1].end_us;
  for (LabeledInterval& interval : intervals) {
    if (interval.label == "SIL") interval.label.clear();
  }
  return intervals;
}

void expect_identical(const Track& actual, const Track& expected) {
  ASSERT_EQ(actual.frame_count(), expected.frame_count());
  EXPECT_EQ(actual.t_us, expected.t_us);
  EXPECT_EQ(actual.kinds, expected.kinds);
  ASSERT_EQ(actual.values.size(), expected.values.size());
  EXPECT_EQ(0, std::memcmp(actual.values.data(), expected.values.data(), actual.values.size() * sizeof(float)));
}

TEST(LiveRenderer, FinalPhonemesBeforeAnyDeadlineGiveTheOfflineRender) {
  const Fixture f;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const auto phonemes = contiguous_utterance(60, seed);
    LiveRenderer live = f.renderer();
    Track track = f.empty_track();
    for (const LabeledInterval& phoneme : phonemes) live.push_final(phoneme, track);
    live.finish(track);
    expect_identical(track, f.offline(phonemes));
  }
}

TEST(LiveRenderer, AGuessThatIsTheTruthGivesTheOfflineRenderWhateverTheDeadlines) {
  // Each phoneme becomes final two phonemes after it is first guessed; every 20 ms a deadline
  // 150 ms behind the newest audio: the frames are those of the whole utterance rendered offline.
  const Fixture f;
  for (std::uint64_t seed = 1; seed <= 5; ++seed) {
    const auto phonemes = contiguous_utterance(60, seed);
    LiveRenderer live = f.renderer();
    Track track = f.empty_track();
    std::size_t final_count = 0;
    const std::int64_t end_us = phonemes.back().end_us;
    for (std::int64_t heard_us = 20'000; heard_us < end_us; heard_us += 20'000) {
      // Final: the phonemes that ended more than two phonemes before what was heard.
      std::size_t heard_count = 0;
      while (heard_count < phonemes.size() && phonemes[heard_count].start_us < heard_us) ++heard_count;
      while (final_count + 2 < heard_count) live.push_final(phonemes[final_count++], track);
      // The guess: the rest of the truth (the recogniser guessed right).
      const std::vector<LabeledInterval> guess(phonemes.begin() + static_cast<std::ptrdiff_t>(final_count),
                                               phonemes.end());
      live.emit_until(heard_us - 150'000, guess, track);
      if (!track.t_us.empty()) {
        EXPECT_LE(track.t_us.back(), std::max<std::int64_t>(heard_us - 150'000, 0));
      }
    }
    while (final_count < phonemes.size()) live.push_final(phonemes[final_count++], track);
    live.finish(track);
    SCOPED_TRACE("seed " + std::to_string(seed));
    expect_identical(track, f.offline(phonemes));
  }
}

TEST(LiveRenderer, WrongGuessesStillGiveEachFrameOnceInTimeOrderAndNeverPastItsDeadline) {
  const Fixture f;
  const auto phonemes = contiguous_utterance(80, 9);
  const char* labels[] = {"AA", "M", "IY", "P", "S", "", "UW", "F", "XQ"};  // XQ: a guess the phone set lacks
  std::mt19937 random(3);
  LiveRenderer live = f.renderer();
  Track track = f.empty_track();
  std::size_t final_count = 0;
  const std::int64_t end_us = phonemes.back().end_us;
  for (std::int64_t heard_us = 20'000; heard_us < end_us; heard_us += 20'000) {
    const std::size_t before = track.frame_count();
    while (final_count < phonemes.size() && phonemes[final_count].end_us + 400'000 <= heard_us) {
      live.push_final(phonemes[final_count++], track);
    }
    // A random guess from the final phonemes' end to what was heard.
    std::vector<LabeledInterval> guess;
    for (std::int64_t t = live.final_end_us(); t < heard_us;) {
      const std::int64_t end = std::min(heard_us, t + 20'000 + static_cast<std::int64_t>(random() % 120'000));
      guess.push_back({labels[random() % std::size(labels)], t, end, 0});
      t = end;
    }
    live.emit_until(heard_us - 150'000, guess, track);
    for (std::size_t k = before; k < track.frame_count(); ++k) {
      EXPECT_LE(track.t_us[k], heard_us - 150'000) << "frame " << k;
    }
  }
  while (final_count < phonemes.size()) live.push_final(phonemes[final_count++], track);
  live.finish(track);
  EXPECT_TRUE(std::adjacent_find(track.t_us.begin(), track.t_us.end(), std::greater_equal<>()) == track.t_us.end());
  EXPECT_EQ(track.t_us.front(), 0);
  // The stream reaches as far as the offline render does.
  EXPECT_EQ(track.t_us.back(), f.offline(phonemes).t_us.back());
  for (const float value : track.values) EXPECT_TRUE(std::isfinite(value));
}

}  // namespace
}  // namespace lipsync
