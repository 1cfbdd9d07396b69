// The whole pipeline on real TTS output (Festival and flite, committed under
// tests/data/formats/ by regenerate.sh there): parse, map through the phone
// set, split stops, render with the built-in model, and check what a viewer
// would check: the closing channels reach the closure's targets (within 5 %) at
// both key frames of every /p b m/ closure, and the mouth opens on open vowels.
// (tests/core/closure_real_speech_test.cpp does the same over a larger corpus.)
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "../support/closure_frames.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"

namespace lipsync {
namespace {

struct Rendered {
  std::vector<Segment> segments;
  Track track;
};

Rendered render_fixture(const std::string& name, InputFormat format) {
  const std::string path = std::string(LIPSYNC_TEST_DATA_DIR) + "/formats/" + name;
  std::ifstream file(path, std::ios::binary);
  EXPECT_TRUE(file) << "missing fixture " << path;
  std::stringstream text;
  text << file.rdbuf();
  const ArticulationModel& model = ArticulationModel::builtin();
  const LabeledUtterance utterance = parse_utterance(text.str(), format, name);
  const PhoneSet radio = *PhoneSet::builtin("radio", model);
  Rendered rendered;
  rendered.segments = build_segments(utterance, model, radio);
  rendered.track = render_track(model, rendered.segments, {.fps = 30});
  return rendered;
}

std::size_t channel(std::string_view name) {
  const auto& channels = ArticulationModel::builtin().channels();
  for (std::size_t c = 0; c < channels.size(); ++c) {
    if (channels[c].name == name) return c;
  }
  ADD_FAILURE() << "no channel " << name;
  return 0;
}

/// `open_at_least`: the widest jaw opening the utterance's vowels must reach.
void expect_closures_are_shut(const Rendered& rendered, const std::string& name, float open_at_least) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const std::size_t jaw = channel("jaw_rotation");
  const Track& track = rendered.track;
  std::size_t bilabial_closures = 0;
  for (const Segment& segment : rendered.segments) {
    const std::string& phoneme = model.phoneme(segment.phoneme).name;
    if (!testing::is_bilabial_closure(phoneme)) continue;
    ++bilabial_closures;
    for (std::int64_t key_time : {segment.start_us, segment.end_us}) {
      const auto it = std::find(track.t_us.begin(), track.t_us.end(), key_time);
      ASSERT_NE(it, track.t_us.end()) << name << ": no key frame at " << key_time << " µs (" << phoneme << ")";
      EXPECT_NE(track.kinds[static_cast<std::size_t>(it - track.t_us.begin())], FrameKind::uniform)
          << name << " at " << key_time;
    }
    for (std::size_t f = 0; f < track.frame_count(); ++f) {
      if (track.t_us[f] > segment.start_us && track.t_us[f] < segment.end_us) {
        ADD_FAILURE() << name << ": frame inside the closure " << phoneme << " at " << track.t_us[f] << " µs";
      }
    }
  }
  EXPECT_GT(bilabial_closures, 0U) << name;
  for (const auto& closure : testing::closure_frames(model, rendered.segments, track)) {
    EXPECT_LE(testing::closure_error(model, rendered.segments, track, closure), testing::kClosureTolerance)
        << name << ": /" << closure.phoneme << "/ not closed at " << track.t_us[closure.frame] << " µs";
  }
  float widest = 0.0F;
  for (std::size_t f = 0; f < track.frame_count(); ++f) widest = std::max(widest, track.frame_values(f)[jaw]);
  EXPECT_GT(widest, open_at_least) << name << ": the vowels never open the mouth";
}

TEST(RealSpeech, FestivalMamaMadeABubbleShutsTheLipsAtEveryBilabial) {
  // Open /aa/ between the /m/s: the jaw swings wide and back.
  expect_closures_are_shut(render_fixture("festival_mama.lab", InputFormat::lab), "festival_mama.lab", 0.3F);
}

TEST(RealSpeech, FliteSpeechSynchronizationShutsTheLipsForThePInSpeech) {
  const Rendered rendered = render_fixture("flite_speech_synchronization.psdur", InputFormat::flite);
  expect_closures_are_shut(rendered, "flite_speech_synchronization.psdur", 0.2F);  // mid and close vowels
  // flite's /p/ has no closure label: the segment builder split it.
  std::vector<std::string> names;
  for (const Segment& s : rendered.segments) names.push_back(ArticulationModel::builtin().phoneme(s.phoneme).name);
  EXPECT_THAT(names, ::testing::IsSupersetOf({"pcl", "p"}));
}

TEST(RealSpeech, TimitStyleClosuresRenderLikeTheSplitStops) {
  // The same word with TIMIT's explicit closure labels: key frames at the
  // closure's ends exactly where the labels put them.
  const std::string path = std::string(LIPSYNC_TEST_DATA_DIR) + "/formats/speech.PHN";
  std::ifstream file(path);
  ASSERT_TRUE(file) << path;
  std::stringstream text;
  text << file.rdbuf();
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet timit = *PhoneSet::builtin("timit", model);
  Rendered rendered;
  rendered.segments = build_segments(parse_utterance(text.str(), InputFormat::timit, "speech.PHN"), model, timit);
  rendered.track = render_track(model, rendered.segments, {.fps = 20});
  expect_closures_are_shut(rendered, "speech.PHN", 0.08F);  // /i/ is a close vowel
}

}  // namespace
}  // namespace lipsync
