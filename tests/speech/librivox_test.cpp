// Human speech: the five LibriVox sentences of Debian's pocketsphinx-testdata (read
// speech, 16 kHz, with transcripts), aligned with their transcripts and without, and
// rendered.
//
// No phone-level truth comes with them, so boundary errors cannot be measured here
// (tests/bench/alignment_accuracy does that on synthetic speech). What can be checked
// without it: every word of the transcript is placed (without it, the words heard are
// mostly the words said); every /p b m/ the alignment
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

struct BilabialCounts {
  int bilabials = 0, moved = 0;
  double least_below_peak_db = 200;
};

// Renders `aligned` (of `audio`, read from `path`) and checks every /p b m/ of it: sealed key
// frames, and the formant band at least kClosureBelowPeakDb below the sentence's peak between
// the first and the last of them.
void check_bilabials(const speech::Alignment& aligned, const speech::PcmAudio& audio, const std::string& path,
                     BilabialCounts& counts) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  for (const speech::RefinedBoundary& boundary : aligned.refined) counts.moved += boundary.moved;
  const std::vector<double> levels = speech::formant_band_levels_db(speech::resample(audio, 16000), 10'000, 1'000);
  const double peak = *std::max_element(levels.begin(), levels.end());
  const std::vector<Segment> segments = build_segments(aligned.phones, model, arpabet);
  const Track track = render_track(model, segments, {.fps = 30});
  const auto frames = testing::closure_frames(model, segments, track);
  std::vector<float> shapes(kArkitNames.size());
  for (const LabeledInterval& phone : aligned.phones.intervals) {
    if (phone.label != "P" && phone.label != "B" && phone.label != "M") continue;
    ++counts.bilabials;
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
      const auto at = static_cast<std::size_t>(std::clamp<std::int64_t>(t_ms - 5, 0, std::int64_t(levels.size()) - 1));
      quietest_below_peak_db = std::max(quietest_below_peak_db, peak - levels[at]);
    }
    const bool sealed_and_quiet = first_us >= 0 && quietest_below_peak_db >= kClosureBelowPeakDb;
    if (first_us >= 0) counts.least_below_peak_db = std::min(counts.least_below_peak_db, quietest_below_peak_db);
    seen += "; the quietest 10 ms between the sealed ones is " + std::to_string(quietest_below_peak_db) +
            " dB below the peak";
    EXPECT_TRUE(sealed_and_quiet) << path << ": /" << phone.label << "/ [" << phone.start_us << ", " << phone.end_us
                                  << "] µs: key frames" << (seen.empty() ? " none" : seen);
  }
}

speech::PcmAudio read_wav(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return speech::decode_wav(bytes, path).audio;
}

TEST(LibriVox, EveryBilabialGetsASealedKeyFrameInsideAQuietStretchOfTheSignal) {
  if (::access(kDir, R_OK) != 0) GTEST_SKIP() << kDir << " missing (apt-get install pocketsphinx-testdata)";
  const std::vector<Recording> recordings = librivox();
  ASSERT_EQ(recordings.size(), 5U);
  BilabialCounts counts;
  for (const Recording& recording : recordings) {
    const std::string path = std::string(kDir) + recording.name + ".wav";
    const speech::PcmAudio audio = read_wav(path);
    speech::AlignmentOptions options;
    options.transcript = recording.transcript;
    const speech::Alignment aligned = speech::align_speech(audio, path, options);
    EXPECT_EQ(aligned.words.size(), speech::transcript_words(recording.transcript).size()) << path;
    check_bilabials(aligned, audio, path, counts);
  }
  std::printf(
      "[ measured ] %d bilabials in 5 LibriVox sentences; %d lip boundaries moved by the refiner; the "
      "least quiet sealed closure reaches %.1f dB below its sentence's peak\n",
      counts.bilabials, counts.moved, counts.least_below_peak_db);
  EXPECT_GE(counts.bilabials, 20);
}

// Without the transcript the words PocketSphinx hears in this read speech fit (they are close
// to the transcript), and the /p b m/ of those words pass the same checks.
TEST(LibriVox, WithoutATranscriptTheWordsHeardAreAlignedAndEveryBilabialStillSitsInAQuietStretch) {
  if (::access(kDir, R_OK) != 0) GTEST_SKIP() << kDir << " missing (apt-get install pocketsphinx-testdata)";
  const std::vector<Recording> recordings = librivox();
  ASSERT_EQ(recordings.size(), 5U);
  BilabialCounts counts;
  int words = 0, heard_right = 0;
  for (const Recording& recording : recordings) {
    const std::string path = std::string(kDir) + recording.name + ".wav";
    const speech::PcmAudio audio = read_wav(path);
    const speech::Alignment aligned = speech::align_speech(audio, path, {});
    ASSERT_FALSE(aligned.words.empty()) << path << ": the words heard did not fit";
    const std::vector<std::string> said = speech::transcript_words(recording.transcript);
    words += static_cast<int>(said.size());
    for (const LabeledInterval& word : aligned.words)
      heard_right += std::find(said.begin(), said.end(), word.label) != said.end() ? 1 : 0;
    check_bilabials(aligned, audio, path, counts);
  }
  std::printf("[ measured ] without transcripts: %d of %d heard words are in the transcripts; %d bilabials\n",
              heard_right, words, counts.bilabials);
  EXPECT_GE(heard_right * 5, words * 3);  // most words heard are words said (measured: 51 of 71)
  EXPECT_GE(counts.bilabials, 20);
}

}  // namespace
}  // namespace lipsync
