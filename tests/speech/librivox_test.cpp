// Human speech: the five LibriVox sentences of Debian's pocketsphinx-testdata (read
// speech, 16 kHz, with transcripts), aligned with their transcripts and rendered.
//
// No phone-level truth comes with them, so boundary errors cannot be measured here
// (tests/bench/alignment_accuracy does that on synthetic speech). What can be checked
// without it: every word of the transcript is placed; every /p b m/ the alignment
// has gets key frames whose mouth is sealed in ARKit (mouthClose >= jawOpen - 0.02),
// and between the first and last of them the signal's formant band (400 to 3500 Hz)
// falls far below the sentence's speech, as it does in a real lip closure.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "../support/closure_frames.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/closure_refiner.hpp"

namespace lipsync {
namespace {

constexpr const char* kDir = "/usr/share/pocketsphinx/test/data/librivox/";
// Between a bilabial's first and last sealed key frame some 10 ms must be at least this far
// below the sentence's loudest 10 ms in the formant band.
constexpr double kClosureBelowPeakDb = 20.0;

struct Recording {
  std::string name, transcript;
};

std::vector<Recording> librivox() {
  std::vector<Recording> recordings;
  std::ifstream file(std::string(kDir) + "transcription");
  for (std::string line; std::getline(file, line);) {
    const auto open = line.rfind('('), close = line.rfind(')');
    if (open == std::string::npos || close == std::string::npos) continue;
    std::string text = line.substr(0, open);
    for (const char* tag : {"<s>", "</s>"}) {
      if (const auto at = text.find(tag); at != std::string::npos) text.erase(at, std::string(tag).size());
    }
    recordings.push_back({line.substr(open + 1, close - open - 1), text});
  }
  return recordings;
}

std::size_t arkit(std::string_view name) {
  return static_cast<std::size_t>(std::find(kArkitNames.begin(), kArkitNames.end(), name) - kArkitNames.begin());
}

TEST(LibriVox, EveryBilabialGetsASealedKeyFrameInsideAQuietStretchOfTheSignal) {
  if (::access(kDir, R_OK) != 0) GTEST_SKIP() << kDir << " missing (apt-get install pocketsphinx-testdata)";
  const std::vector<Recording> recordings = librivox();
  ASSERT_EQ(recordings.size(), 5U);
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  int bilabials = 0, moved = 0;
  double least_below_peak_db = 200;
  for (const Recording& recording : recordings) {
    const std::string path = std::string(kDir) + recording.name + ".wav";
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const speech::PcmAudio audio = speech::decode_wav(bytes, path).audio;
    speech::AlignmentOptions options;
    options.transcript = recording.transcript;
    const speech::Alignment aligned = speech::align_speech(audio, path, options);
    EXPECT_EQ(aligned.words.size(), speech::transcript_words(recording.transcript).size()) << path;
    for (const speech::RefinedBoundary& boundary : aligned.refined) moved += boundary.moved;

    const std::vector<double> levels = speech::formant_band_levels_db(speech::resample(audio, 16000), 10'000, 1'000);
    const double peak = *std::max_element(levels.begin(), levels.end());
    const std::vector<Segment> segments = build_segments(aligned.phones, model, arpabet);
    const Track track = render_track(model, segments, {.fps = 30});
    const auto frames = testing::closure_frames(model, segments, track);
    std::vector<float> shapes(kArkitNames.size());
    for (const LabeledInterval& phone : aligned.phones.intervals) {
      if (phone.label != "P" && phone.label != "B" && phone.label != "M") continue;
      ++bilabials;
      // The sealed closure key frames of this phone, and the quietest 10 ms between its first and last.
      std::int64_t first_us = -1, last_us = -1;
      std::string seen;
      for (const auto& closure : frames) {
        const std::int64_t t_us = track.t_us[closure.frame];
        if (closure.place != testing::ClosurePlace::bilabial || t_us < phone.start_us || t_us > phone.end_us) continue;
        model.retarget_to_arkit(track.frame_values(closure.frame), shapes);
        const double seal = shapes[arkit("mouthClose")] - shapes[arkit("jawOpen")];
        seen += " " + std::to_string(t_us) + " µs (mouthClose - jawOpen " + std::to_string(seal) + ")";
        if (seal < -0.02) continue;
        if (first_us < 0) first_us = t_us;
        last_us = t_us;
      }
      double quietest_below_peak_db = 0;
      for (std::int64_t t_ms = first_us / 1000; first_us >= 0 && t_ms <= last_us / 1000; ++t_ms) {
        const auto at =
            static_cast<std::size_t>(std::clamp<std::int64_t>(t_ms - 5, 0, std::int64_t(levels.size()) - 1));
        quietest_below_peak_db = std::max(quietest_below_peak_db, peak - levels[at]);
      }
      const bool sealed_and_quiet = first_us >= 0 && quietest_below_peak_db >= kClosureBelowPeakDb;
      if (first_us >= 0) least_below_peak_db = std::min(least_below_peak_db, quietest_below_peak_db);
      seen += "; the quietest 10 ms between the sealed ones is " + std::to_string(quietest_below_peak_db) +
              " dB below the peak";
      EXPECT_TRUE(sealed_and_quiet) << path << ": /" << phone.label << "/ [" << phone.start_us << ", " << phone.end_us
                                    << "] µs: key frames" << (seen.empty() ? " none" : seen);
    }
  }
  std::printf(
      "[ measured ] %d bilabials in 5 LibriVox sentences; %d lip boundaries moved by the refiner; the "
      "least quiet sealed closure reaches %.1f dB below its sentence's peak\n",
      bilabials, moved, least_below_peak_db);
  EXPECT_GE(bilabials, 20);
}

}  // namespace
}  // namespace lipsync
