// Recorded speech in other languages: `lipsync align/render X.wav --voice V` aligns against
// espeak-ng's rendering of the transcript (lipsync/speech/dtw_aligner.hpp), checked on real
// Festival recordings in Italian, Czech, Catalan, Hindi and Finnish (tests/data/recorded_languages, made by
// tools/speech/measure_language_alignment.py --corpus), whose own segment times are the truth.
//
// - Boundaries: median error ≤ 30 ms, 95th percentile ≤ 100 ms, bilabial closures within
//   30 ms ≥ 80 % (the goals of docs/languages.md), over the boundaries the regenerate script
//   matched between Festival's segments and espeak-ng's phonemes (NAME.truth.tsv); and, so that
//   a regression fails, no worse than this corpus measures today with some margin (median
//   ≤ 15 ms, p95 ≤ 60 ms, bilabials ≥ 97 %: today 42 of 43, among them a Catalan /b/ that
//   espeak-ng says as /β/, refined as a /b/). No bilabial closure is more than 100 ms off (the
//   Finnish /m/ of "aamulla" was 275 ms early before the warp charged long runs). A stop after a
//   pause, and one after a nasal (the /m b/ of Italian "bambino"), starts at its closure, not at
//   its burst.
// - Through the render path the aligned phonemes render with the lips sealed at every bilabial
//   key frame, and `lipsync render X.wav --text-file F --voice V` works.
// - Bad inputs (empty transcript, silence, noise, a transcript far too long for the audio, an
//   unknown voice, --aligner pocketsphinx with a non-English voice) are errors naming the file
//   and what is wrong, with a non-zero exit.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "../support/child_process.hpp"
#include "../support/closure_frames.hpp"
#include "../support/lipsync_cli_test.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/speech/dtw_aligner.hpp"

namespace lipsync {
namespace {

using ::testing::HasSubstr;

const std::filesystem::path kCorpus = std::filesystem::path(LIPSYNC_TEST_DATA_DIR) / "recorded_languages";
constexpr const char* kItems[] = {"it_3", "cs_1", "ca_1", "cs_2", "hi_3", "it_1", "fi_2"};

const ArticulationModel& model() { return ArticulationModel::builtin(); }

const PhoneSet& phone_set(const std::string& name) {
  static const std::vector<PhoneSet> sets = PhoneSet::builtin_all(model());
  for (const PhoneSet& set : sets) {
    if (set.name() == name) return set;
  }
  throw std::logic_error("no phone set " + name);
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream file(path, std::ios::binary);
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

struct CorpusItem {
  std::string name, voice, transcript;
  speech::PcmAudio audio;
};

CorpusItem load(const std::string& name) {
  CorpusItem item;
  item.name = name;
  std::istringstream text(read_file(kCorpus / (name + ".txt")));
  std::getline(text, item.voice);
  std::getline(text, item.transcript);
  const std::string wav = (kCorpus / (name + ".wav")).string();
  item.audio = speech::decode_wav(read_file(wav), wav).audio;
  return item;
}

speech::Alignment align(const CorpusItem& item) {
  speech::DtwAlignmentOptions options;
  options.transcript = item.transcript;
  options.synthesis.voice = item.voice;
  return speech::align_speech_to_synthesis(item.audio, item.name + ".wav", options);
}

double percentile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  return values[std::min(values.size() - 1, static_cast<std::size_t>(std::lround(q * double(values.size() - 1))))];
}

// The errors of some bilabial closures, ms, each named "NAME: LABEL error ms" for the messages.
struct NamedErrors {
  std::vector<double> ms;
  std::vector<std::string> names;

  void add(const std::string& item, const std::string& label, double error_ms) {
    ms.push_back(error_ms);
    names.push_back(item + ": " + label + " " + std::to_string(std::lround(error_ms)) + " ms");
  }
};

// The errors of the corpus's scored boundaries, ms.
struct CorpusErrors {
  std::vector<double> boundaries_ms;
  NamedErrors bilabials;           ///< every bilabial closure
  NamedErrors stops_after_pauses;  ///< bilabial stops after a pause
  NamedErrors stops_after_nasals;  ///< bilabial stops after a nasal (/m b/, /n b/)
};

bool is_nasal(const std::string& label) { return label.starts_with("m") || label.starts_with("n"); }

CorpusErrors measure_corpus() {
  CorpusErrors errors;
  for (const char* name : kItems) {
    const CorpusItem item = load(name);
    const speech::Alignment alignment = align(item);
    EXPECT_EQ(alignment.phones.phone_set, "ipa") << name;
    const auto& phones = alignment.phones.intervals;
    EXPECT_FALSE(phones.empty()) << name;
    if (phones.empty()) continue;
    EXPECT_EQ(phones.front().start_us, 0) << name;
    EXPECT_EQ(phones.back().end_us, item.audio.duration_us()) << name;
    std::istringstream truth(read_file(kCorpus / (std::string(name) + ".truth.tsv")));
    std::string line;
    while (std::getline(truth, line)) {
      if (line.empty() || line.front() == '#') continue;
      std::istringstream fields(line);
      std::string festival_label, aligned_label;
      double festival_start_s = 0;
      std::size_t index = 0;
      int kind = 0;
      fields >> festival_label >> festival_start_s >> index >> aligned_label >> kind;
      EXPECT_LT(index, phones.size()) << name << ": " << line;
      if (index >= phones.size()) continue;
      // espeak-ng's phonemes for the transcript are those the truth was matched to.
      EXPECT_EQ(phones[index].label, aligned_label) << name << ": phone " << index;
      const double error_ms = std::abs(double(phones[index].start_us) / 1000.0 - 1000.0 * festival_start_s);
      if (kind & 1) errors.boundaries_ms.push_back(error_ms);
      if (kind & 2) errors.bilabials.add(name, aligned_label, error_ms);
      const bool stop = aligned_label == "p" || aligned_label == "b";
      if (!(kind & 2) || !stop || index == 0) continue;
      if (phones[index - 1].label.empty()) errors.stops_after_pauses.add(name, aligned_label, error_ms);
      if (is_nasal(phones[index - 1].label)) errors.stops_after_nasals.add(name, aligned_label, error_ms);
    }
  }
  return errors;
}

std::size_t count_within_30_ms(const std::vector<double>& errors_ms) {
  return static_cast<std::size_t>(
      std::count_if(errors_ms.begin(), errors_ms.end(), [](double error_ms) { return error_ms <= 30.0; }));
}

TEST(RecordedLanguages, BoundariesOnFestivalRecordingsMeetTheGoals) {
  const CorpusErrors errors = measure_corpus();
  ASSERT_GE(errors.boundaries_ms.size(), 150U);
  ASSERT_GE(errors.bilabials.ms.size(), 30U);
  const double median_ms = percentile(errors.boundaries_ms, 0.5);
  const double p95_ms = percentile(errors.boundaries_ms, 0.95);
  const std::size_t close = count_within_30_ms(errors.bilabials.ms);
  const double bilabial_share = double(close) / double(errors.bilabials.ms.size());
  std::printf("[ measured ] %zu boundaries: median %.1f ms, p95 %.1f ms; bilabial closures within 30 ms: %zu of %zu\n",
              errors.boundaries_ms.size(), median_ms, p95_ms, close, errors.bilabials.ms.size());
  EXPECT_LE(median_ms, 30.0);
  EXPECT_LE(p95_ms, 100.0);
  EXPECT_GE(bilabial_share, 0.8);
  // Today's figures with a margin: a change that loses ground fails here.
  EXPECT_LE(median_ms, 15.0);
  EXPECT_LE(p95_ms, 60.0);
  EXPECT_GE(bilabial_share, 0.97);
}

TEST(RecordedLanguages, NoBilabialClosureIsGrosslyOff) {
  // A frame of espeak-ng's that is only a little closer must not take a whole stretch of the recording:
  // the /m/ of Finnish "leipaa aamulla" (fi_2), after a vowel Festival says a little longer than
  // espeak-ng and with a dip in its level between the words, was 275 ms early when one frame of
  // espeak-ng's /m/ could take 310 ms of the vowel at no more than the frames' distance (StretchCost).
  // The worst left is the /m/ of Italian "le mele" (it_3), 90 ms early.
  const CorpusErrors errors = measure_corpus();
  for (std::size_t k = 0; k < errors.bilabials.ms.size(); ++k) {
    EXPECT_LE(errors.bilabials.ms[k], 100.0) << errors.bilabials.names[k];
  }
}

TEST(RecordedLanguages, StopsAfterAPauseStartAtTheirClosure) {
  // Both audios start such a stop at its burst (its closure is as silent as the pause); the aligner
  // gives it a closure before the burst, so the lips close before the sound starts.
  const CorpusErrors errors = measure_corpus();
  ASSERT_GE(errors.stops_after_pauses.ms.size(), 2U);
  for (std::size_t k = 0; k < errors.stops_after_pauses.ms.size(); ++k) {
    EXPECT_LE(errors.stops_after_pauses.ms[k], 30.0) << errors.stops_after_pauses.names[k];
  }
}

TEST(RecordedLanguages, StopsAfterANasalStartAtTheirClosure) {
  // The nasal's closure goes on into the stop (/m b/ of "bambino", /n b/ of "un bicchiere"), and
  // espeak-ng's nasal lasts until the burst; the aligner gives the stop a closure before its burst.
  const CorpusErrors errors = measure_corpus();
  ASSERT_GE(errors.stops_after_nasals.ms.size(), 2U);
  for (std::size_t k = 0; k < errors.stops_after_nasals.ms.size(); ++k) {
    EXPECT_LE(errors.stops_after_nasals.ms[k], 30.0) << errors.stops_after_nasals.names[k];
  }
}

TEST(RecordedLanguages, AlignedBilabialsRenderWithTheLipsSealed) {
  std::size_t bilabial_frames = 0;
  for (const char* name : kItems) {
    const CorpusItem item = load(name);
    LabeledUtterance phones = align(item).phones;
    speech::cover_audio(phones, item.audio.duration_us(), 30);
    const std::vector<Segment> segments = build_segments(phones, model(), phone_set(phones.phone_set));
    const Track track = render_track(model(), segments);
    std::vector<float> shapes(kArkitNames.size());
    const auto arkit = [](std::string_view shape) {
      return static_cast<std::size_t>(std::find(kArkitNames.begin(), kArkitNames.end(), shape) - kArkitNames.begin());
    };
    for (const auto& closure : testing::closure_frames(model(), segments, track)) {
      std::string channel;
      EXPECT_LE(testing::closure_error(model(), segments, track, closure, &channel), testing::kClosureTolerance)
          << name << ": /" << closure.phoneme << "/ at " << track.t_us[closure.frame] << " µs, " << channel;
      if (closure.place != testing::ClosurePlace::bilabial) continue;
      ++bilabial_frames;
      model().retarget_to_arkit(track.frame_values(closure.frame), shapes);
      EXPECT_GE(shapes[arkit("mouthClose")] - shapes[arkit("jawOpen")], -0.02F)
          << name << ": /" << closure.phoneme << "/ at " << track.t_us[closure.frame] << " µs";
    }
  }
  EXPECT_GE(bilabial_frames, 20U);
}

TEST(RecordedLanguages, TheWarpFollowsARecordingSpokenSlowerThanEspeakNg) {
  // The same Italian words from espeak-ng at 120 words per minute, aligned against its own
  // rendering at the default 175: a warp of 1.5x, every boundary known exactly.
  speech::SynthesisOptions slow;
  slow.voice = "it";
  slow.words_per_minute = 120;
  const CorpusItem item = load("it_3");
  const speech::Synthesis recording = speech::synthesize(item.transcript, slow);
  speech::DtwAlignmentOptions options;
  options.transcript = item.transcript;
  options.synthesis.voice = "it";
  const speech::Alignment alignment = speech::align_speech_to_synthesis(recording.audio, "slow.wav", options);
  // The aligned phones: a pause for the padding before espeak-ng's (which has none), then its own.
  ASSERT_EQ(alignment.phones.intervals.size(), recording.phonemes.intervals.size() + 1);
  std::vector<double> errors_ms;
  for (std::size_t k = 1; k < recording.phonemes.intervals.size(); ++k) {
    const auto& truth = recording.phonemes.intervals[k];
    const auto& aligned = alignment.phones.intervals[k + 1];
    ASSERT_EQ(aligned.label, truth.label) << k;
    // A stop starts at its burst in espeak-ng's events and at its closure in the alignment.
    if (std::string_view("pbtdkg").find(truth.label.front()) != std::string_view::npos) continue;
    errors_ms.push_back(std::abs(double(aligned.start_us - truth.start_us)) / 1000.0);
  }
  std::printf("[ measured ] espeak-ng at 120 wpm against 175: median %.1f ms, p95 %.1f ms\n",
              percentile(errors_ms, 0.5), percentile(errors_ms, 0.95));
  ASSERT_GE(errors_ms.size(), 20U);
  EXPECT_LE(percentile(errors_ms, 0.5), 30.0);
  EXPECT_LE(percentile(errors_ms, 0.95), 100.0);
}

TEST(RecordedLanguages, AStopThatTakesOverTheShortPauseBeforeItLeavesEveryLabelOnItsOwnInterval) {
  // espeak-ng's Catalan puts a short pause before the /p/ of "per" (its closure, as silent as a
  // pause); the closure refiner gives that pause to the stop and drops it. The phones after it must
  // keep their own times: the aligned phones tile the recording, in espeak-ng's order.
  const std::string transcript = "Ma mare prepara un bon sopar per a tothom.";
  speech::SynthesisOptions slow;
  slow.voice = "ca";
  slow.words_per_minute = 140;
  const speech::Synthesis recording = speech::synthesize(transcript, slow);
  speech::DtwAlignmentOptions options;
  options.transcript = transcript;
  options.synthesis.voice = "ca";
  const speech::Alignment alignment = speech::align_speech_to_synthesis(recording.audio, "slow_ca.wav", options);
  const std::vector<LabeledInterval>& phones = alignment.phones.intervals;
  ASSERT_FALSE(phones.empty());
  EXPECT_EQ(phones.front().start_us, 0);
  EXPECT_EQ(phones.back().end_us, recording.audio.duration_us());
  for (std::size_t k = 0; k < phones.size(); ++k) {
    EXPECT_LT(phones[k].start_us, phones[k].end_us) << k << " /" << phones[k].label << "/";
    if (k > 0) {
      EXPECT_EQ(phones[k].start_us, phones[k - 1].end_us) << k << " /" << phones[k].label << "/";
    }
  }
  const auto spoken = [](const std::vector<LabeledInterval>& intervals) {
    std::vector<std::string> labels;
    for (const LabeledInterval& interval : intervals) {
      if (!interval.label.empty()) labels.push_back(interval.label);
    }
    return labels;
  };
  EXPECT_THAT(spoken(phones), ::testing::ElementsAreArray(spoken(recording.phonemes.intervals)));
  EXPECT_EQ(phones.back().label, "") << "the pause after the last /m/";
}

// --- the command line ------------------------------------------------------------------------

class RecordedLanguagesCli : public testing::LipsyncCliTest {
 protected:
  void write_wav(const std::string& name, const std::vector<std::int16_t>& samples) {
    std::ofstream out(dir_ / name, std::ios::binary);
    speech::write_wav(out, speech::PcmAudio{16000, samples});
  }
};

TEST_F(RecordedLanguagesCli, AlignAndRenderTakeAVoice) {
  const std::string wav = (kCorpus / "it_3.wav").string();
  const CorpusItem item = load("it_3");
  testing::write_text(dir_ / "words.txt", item.transcript);
  const testing::RunResult aligned =
      run({"align", wav, "--text", item.transcript, "--voice", "it", "-o", "it.TextGrid"});
  ASSERT_EQ(aligned.status, 0) << aligned.err;
  const std::string grid = testing::read_text(dir_ / "it.TextGrid");
  EXPECT_THAT(grid, HasSubstr("text = \"ɲ\""));  // "Bologna" in espeak-ng's IPA
  const testing::RunResult rendered =
      run({"render", wav, "--text-file", "words.txt", "--voice", "it", "--format", "csv", "-o", "it.csv"});
  ASSERT_EQ(rendered.status, 0) << rendered.err;
  EXPECT_FALSE(testing::read_text(dir_ / "it.csv").empty());
}

TEST_F(RecordedLanguagesCli, BadInputsAreErrorsNamingTheFileAndWhatIsWrong) {
  const std::string wav = (kCorpus / "it_3.wav").string();
  std::mt19937 random(28);
  std::normal_distribution<double> noise(0.0, 3000.0);
  std::vector<std::int16_t> samples(std::size_t{16000} * 4);
  for (auto& sample : samples) sample = static_cast<std::int16_t>(noise(random));
  write_wav("noise.wav", samples);
  write_wav("silence.wav", std::vector<std::int16_t>(32000, 0));
  const std::string sentence = load("it_3").transcript;
  struct Case {
    std::vector<std::string> args;
    std::string file, message;
  };
  const Case cases[] = {
      {{"align", wav, "--text", " ,. ", "--voice", "it"}, wav, "the transcript is empty"},
      {{"align", "silence.wav", "--text", sentence, "--voice", "it"}, "silence.wav", "the audio is silent"},
      {{"align", "noise.wav", "--text", sentence, "--voice", "it"}, "noise.wav", "does not match the transcript"},
      {{"align", wav, "--text", sentence + " " + sentence + " " + sentence + " " + sentence + " " + sentence, "--voice",
        "it"},
       wav,
       "cannot be the transcript"},
      {{"align", wav, "--text", sentence, "--voice", "xx-nope"}, wav, "unknown voice 'xx-nope'"},
      {{"render", wav, "--text", sentence, "--voice", "it", "--aligner", "pocketsphinx"}, "", "knows English only"},
      {{"align", wav, "--voice", "it"}, "", "needs the transcript"},
  };
  for (const Case& test : cases) {
    std::vector<std::string> args = test.args;
    args.insert(args.end(), {"-o", "out.TextGrid"});
    const testing::RunResult result = run(args);
    EXPECT_NE(result.status, 0) << test.message;
    EXPECT_THAT(result.err, HasSubstr(test.message));
    if (!test.file.empty()) {
      EXPECT_THAT(result.err, HasSubstr(test.file + ": ")) << test.message;
    }
    EXPECT_FALSE(std::filesystem::exists(dir_ / "out.TextGrid")) << test.message;
  }
}

}  // namespace
}  // namespace lipsync
