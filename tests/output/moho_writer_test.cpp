// Moho switch data (lipsync/moho_writer.hpp) read back by a parser of the documented layout that
// shares nothing with the writer: "MohoSwitch1", then "FRAME MOUTH" lines, frames from 1, strictly
// increasing, Preston Blair mouths that change from line to line, the last line the rest mouth at
// the end (which may repeat the mouth before it: it marks the end). On the real Festival and
// flite timings of tests/data/closures (and their PocketSphinx alignments) every /p b m/ key frame
// shows MBP on its Moho frame, every closure key frame shows its own mouth, and every other frame
// shows the mouth the track holds there; a closure shorter than a frame still shuts the lips.
#include "lipsync/moho_writer.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "../support/closure_frames.hpp"
#include "../support/timed_segments.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/visemes.hpp"

namespace lipsync {
namespace {

const ArticulationModel& model() { return ArticulationModel::builtin(); }

const std::set<std::string> kPrestonBlairMouths = {"AI", "E", "O", "U", "etc", "L", "WQ", "MBP", "FV", "rest"};

/// The switch data as documented: throws std::runtime_error naming the line for anything else.
struct SwitchData {
  std::vector<std::pair<long long, std::string>> keys;  ///< (frame from 1, mouth)

  /// The mouth shown on `frame` (from 1): the last key at or before it.
  std::string mouth_at(long long frame) const {
    std::string mouth;
    for (const auto& [key_frame, key_mouth] : keys) {
      if (key_frame > frame) break;
      mouth = key_mouth;
    }
    return mouth;
  }
  long long end_frame() const { return keys.back().first; }
};

SwitchData read_switch_data(const std::string& text) {
  std::istringstream lines(text);
  std::string line;
  if (!std::getline(lines, line) || line != "MohoSwitch1") throw std::runtime_error("line 1 is not MohoSwitch1");
  SwitchData data;
  for (int number = 2; std::getline(lines, line); ++number) {
    const auto where = "line " + std::to_string(number) + " '" + line + "': ";
    const auto space = line.find(' ');
    if (space == std::string::npos || space == 0) throw std::runtime_error(where + "not 'FRAME MOUTH'");
    const std::string digits = line.substr(0, space), mouth = line.substr(space + 1);
    if (digits.find_first_not_of("0123456789") != std::string::npos || digits[0] == '0')
      throw std::runtime_error(where + "the frame is not a whole number from 1");
    const long long frame = std::stoll(digits);
    if (!kPrestonBlairMouths.count(mouth)) throw std::runtime_error(where + "not a Preston Blair mouth");
    if (data.keys.empty() && frame != 1) throw std::runtime_error(where + "the first key is not on frame 1");
    if (!data.keys.empty() && frame <= data.keys.back().first) throw std::runtime_error(where + "frame not increasing");
    // A mouth is written where it changes; only the last line (the end, rest) may repeat one.
    if (data.keys.size() >= 2 && data.keys.back().second == data.keys[data.keys.size() - 2].second)
      throw std::runtime_error(where + "follows a line that repeats its mouth before the end");
    data.keys.emplace_back(frame, mouth);
  }
  if (data.keys.empty()) throw std::runtime_error("no keys");
  if (data.keys.back().second != "rest") throw std::runtime_error("the last key is not rest");
  if (!text.empty() && text.back() != '\n') throw std::runtime_error("the last line has no line end");
  return data;
}

/// Rhubarb's own Preston Blair names (its DatExporter), written out here rather than taken from the writer.
std::string preston_blair(const std::string& rhubarb) {
  static const std::map<std::string, std::string> names = {{"A", "MBP"}, {"B", "etc"}, {"C", "E"},
                                                           {"D", "AI"},  {"E", "O"},   {"F", "U"},
                                                           {"G", "FV"},  {"H", "L"},   {"X", "rest"}};
  return names.at(rhubarb);
}

bool is_closure_key_frame(FrameKind kind) { return kind == FrameKind::closure_start || kind == FrameKind::closure_end; }

struct Written {
  Track track;
  VisemeTrack visemes;
  std::int64_t end_us = 0;
  std::string text;
};

Written write(const VisemeClassifier& classifier, const std::vector<Segment>& segments, int track_fps, int moho_fps) {
  Written out;
  out.track = render_track(model(), segments, {.fps = track_fps});
  out.visemes = compute_visemes(classifier, out.track);
  out.end_us = segments.back().end_us;
  std::ostringstream text;
  write_moho_switch(
      {.model = "default", .classifier = classifier, .track = out.track, .visemes = out.visemes, .end_us = out.end_us},
      moho_fps, text);
  out.text = text.str();
  return out;
}

/// The Moho frame (from 1) a time belongs to: the nearest frame instant (n − 1) / fps, half up,
/// kept within the utterance's frames.
long long moho_frame_of(std::int64_t t_us, int fps, long long end_frame) {
  const long long nearest = static_cast<long long>(std::floor(static_cast<double>(t_us) * fps / 1e6 + 0.5)) + 1;
  return std::min(nearest, end_frame - 1);
}

TEST(MohoSwitchData, RealSpeechReadsBackWithEveryClosureKeyFrameOnItsFrame) {
  const VisemeClassifier classifier(model(), {.vocabulary = VisemeVocabulary::rhubarb});
  const auto corpus = testing::load_closure_corpus(LIPSYNC_TEST_DATA_DIR, model());
  ASSERT_GE(corpus.size(), 30U);
  std::size_t bilabial_key_frames = 0, other_closure_key_frames = 0, sampled_frames = 0, decided_by_closures = 0;
  std::set<std::string> mouths_seen;
  for (const auto& spoken : corpus) {
    for (const int track_fps : {30, 60}) {
      for (const int moho_fps : {24, 25, 30}) {
        const std::string label =
            spoken.name + " track " + std::to_string(track_fps) + " fps, Moho " + std::to_string(moho_fps) + " fps";
        const Written written = write(classifier, spoken.segments, track_fps, moho_fps);
        SwitchData data;
        ASSERT_NO_THROW(data = read_switch_data(written.text)) << label << "\n" << written.text;
        // The end: the first frame whose instant is at or after the utterance's end shows rest.
        const auto end_frame =
            static_cast<long long>(std::ceil(static_cast<double>(written.end_us) * moho_fps / 1e6)) + 1;
        ASSERT_EQ(data.end_frame(), end_frame) << label;

        // Closure key frames: the mouth of their own winner on their frame, MBP where a bilabial is.
        const Track& track = written.track;
        std::map<long long, std::set<std::string>> closure_mouths;  // Moho frame → mouths of its key frames
        for (std::size_t f = 0; f < track.frame_count(); ++f) {
          if (!is_closure_key_frame(track.kinds[f])) continue;
          const auto winner = classifier.names()[written.visemes.winners[f]];
          closure_mouths[moho_frame_of(track.t_us[f], moho_fps, end_frame)].insert(preston_blair(winner));
        }
        for (const auto& closure : testing::closure_frames(model(), spoken.segments, track)) {
          if (closure.place != testing::ClosurePlace::bilabial || !is_closure_key_frame(track.kinds[closure.frame]))
            continue;
          const long long frame = moho_frame_of(track.t_us[closure.frame], moho_fps, end_frame);
          EXPECT_EQ(data.mouth_at(frame), "MBP") << label << ": /" << closure.phoneme << "/ key frame at "
                                                 << track.t_us[closure.frame] << " us, Moho frame " << frame;
          ++bilabial_key_frames;
        }
        for (const auto& [frame, mouths] : closure_mouths) {
          const std::string shown = data.mouth_at(frame);
          EXPECT_TRUE(mouths.count(shown) && (shown == "MBP" || !mouths.count("MBP")))
              << label << ": Moho frame " << frame << " shows " << shown;
          ++other_closure_key_frames;
        }
        // Every other frame shows the mouth of the last track frame nearest to it or to an earlier one.
        for (long long frame = 1; frame < end_frame; ++frame) {
          mouths_seen.insert(data.mouth_at(frame));
          std::string held = "rest";
          for (std::size_t f = 0; f < track.frame_count() && track.t_us[f] <= written.end_us; ++f) {
            if (moho_frame_of(track.t_us[f], moho_fps, end_frame) <= frame) {
              held = preston_blair(classifier.names()[written.visemes.winners[f]]);
            }
          }
          if (closure_mouths.count(frame)) {
            if (held != data.mouth_at(frame)) ++decided_by_closures;
            continue;
          }
          ASSERT_EQ(data.mouth_at(frame), held) << label << ": Moho frame " << frame;
          ++sampled_frames;
        }
      }
    }
  }
  std::cout << "bilabial key frames " << bilabial_key_frames << ", Moho frames with closure key frames "
            << other_closure_key_frames << " (" << decided_by_closures
            << " of them showing the closure where the mouth held at the frame's end differs), sampled Moho frames "
            << sampled_frames << "\n";
  EXPECT_GT(bilabial_key_frames, 1000U);
  // Nine of the ten names (WQ is never written: /w/ has the shape of /uw/ in every vocabulary).
  EXPECT_EQ(mouths_seen, (std::set<std::string>{"AI", "E", "O", "U", "etc", "L", "MBP", "FV", "rest"}));
}

/// Segments of an ARPAbet utterance given as (label, duration ms), starting at 0.

TEST(MohoSwitchData, AClosureShorterThanAFrameStillShowsMBP) {
  const VisemeClassifier classifier(model(), {.vocabulary = VisemeVocabulary::rhubarb});
  // An /m/ of 12 ms between open vowels (272–284 ms), inside the 24 fps frame whose instant is
  // 291.7 ms (frame 8, times 270.8–312.5 ms), away from every frame instant.
  const auto segments = testing::timed_segments({{"sil", 100}, {"aa", 172}, {"m", 12}, {"aa", 200}, {"sil", 100}});
  const Written written = write(classifier, segments, 60, 24);
  const SwitchData data = read_switch_data(written.text);
  std::vector<long long> closure_frames;
  for (std::size_t f = 0; f < written.track.frame_count(); ++f) {
    if (!is_closure_key_frame(written.track.kinds[f])) continue;
    EXPECT_EQ(classifier.names()[written.visemes.winners[f]], "A") << "key frame at " << written.track.t_us[f];
    closure_frames.push_back(moho_frame_of(written.track.t_us[f], 24, data.end_frame()));
  }
  ASSERT_EQ(closure_frames, (std::vector<long long>{8, 8})) << "both ends of the closure on Moho frame 8";
  EXPECT_EQ(data.mouth_at(8), "MBP") << written.text;
  EXPECT_EQ(data.mouth_at(6), "AI") << written.text;
}

TEST(MohoSwitchData, AClosureKeyFrameWinsItsFrameOverTheMouthHeldAtItsEnd) {
  // The rule on its own, with the frames' winners given: a closure (280–284 ms) whose release is
  // followed, in the same 24 fps frame (frame 8: 270.8–312.5 ms), by an open mouth at 295 ms.
  // Sampling would show AI on frame 8; the closure's key frames take it. A labiodental closure
  // meeting a bilabial one in a frame gives MBP.
  const VisemeClassifier classifier(model(), {.vocabulary = VisemeVocabulary::rhubarb});
  const auto index = [&](const char* name) {
    return static_cast<std::uint32_t>(std::find(classifier.names().begin(), classifier.names().end(), name) -
                                      classifier.names().begin());
  };
  Track track;
  track.channel_count = model().channel_count();
  VisemeTrack visemes;
  visemes.viseme_count = classifier.viseme_count();
  const auto add = [&](std::int64_t t_us, FrameKind kind, const char* shape) {
    track.t_us.push_back(t_us);
    track.kinds.push_back(kind);
    visemes.winners.push_back(index(shape));
  };
  add(0, FrameKind::uniform, "X");
  add(250'000, FrameKind::uniform, "D");
  add(280'000, FrameKind::closure_start, "A");
  add(284'000, FrameKind::closure_end, "A");
  add(295'000, FrameKind::uniform, "D");
  add(400'000, FrameKind::closure_start, "G");  // /f/ meets /m/ in frame 11 (395.8–437.5 ms)
  add(410'000, FrameKind::closure_end, "G");
  add(410'001, FrameKind::closure_start, "A");
  add(420'000, FrameKind::closure_end, "A");
  add(430'000, FrameKind::uniform, "C");
  add(600'000, FrameKind::uniform, "X");
  std::ostringstream text;
  write_moho_switch(
      {.model = "default", .classifier = classifier, .track = track, .visemes = visemes, .end_us = 600'000}, 24, text);
  EXPECT_EQ(text.str(), "MohoSwitch1\n1 rest\n7 AI\n8 MBP\n9 AI\n11 MBP\n12 E\n15 rest\n16 rest\n");
}

TEST(MohoSwitchData, AnEmptyUtteranceIsTheRestMouth) {
  const VisemeClassifier classifier(model(), {.vocabulary = VisemeVocabulary::rhubarb});
  Track track;
  track.channel_count = model().channel_count();
  const VisemeTrack visemes = compute_visemes(classifier, track);
  std::ostringstream text;
  write_moho_switch({.model = "default", .classifier = classifier, .track = track, .visemes = visemes, .end_us = 0}, 24,
                    text);
  EXPECT_EQ(text.str(), "MohoSwitch1\n1 rest\n");
}

TEST(MohoSwitchData, AnotherVocabularyOrFrameRateIsRefusedNamingIt) {
  const auto segments = testing::timed_segments({{"sil", 100}, {"aa", 200}, {"m", 80}, {"sil", 100}});
  const Track track = render_track(model(), segments, {.fps = 30});
  const VisemeClassifier oculus(model(), {.vocabulary = VisemeVocabulary::oculus});
  const VisemeTrack oculus_visemes = compute_visemes(oculus, track);
  std::ostringstream text;
  try {
    write_moho_switch(
        {.model = "default", .classifier = oculus, .track = track, .visemes = oculus_visemes, .end_us = 480'000}, 24,
        text);
    FAIL() << "oculus visemes accepted";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("rhubarb visemes, got oculus"), std::string::npos) << error.what();
  }
  const VisemeClassifier rhubarb(model(), {.vocabulary = VisemeVocabulary::rhubarb});
  const VisemeTrack visemes = compute_visemes(rhubarb, track);
  for (const int fps : {0, -24, 1001}) {
    try {
      write_moho_switch(
          {.model = "default", .classifier = rhubarb, .track = track, .visemes = visemes, .end_us = 480'000}, fps,
          text);
      FAIL() << fps << " fps accepted";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find("frame rate " + std::to_string(fps)), std::string::npos) << error.what();
    }
  }
  EXPECT_TRUE(text.str().empty()) << "nothing is written for a refused request";
}

}  // namespace
}  // namespace lipsync
