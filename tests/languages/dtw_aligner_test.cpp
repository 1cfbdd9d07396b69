// The parts of the DTW aligner (lipsync/speech/dtw_aligner.hpp, acoustic_features.hpp) on
// made-up signals: MFCC frames every 10 ms with mean zero, the start and end of speech found
// past pauses, a warp of a sequence with itself on the diagonal, boundaries carried across
// a uniform stretch, a frame a little closer kept from taking a whole stretch, a pause
// the recording has and the rendering lacks found at the phone it comes before, an /m/ carried
// into the loud vowel before it started at its murmur, and a voiced /b/ started where its voiced
// closure begins.
#include "lipsync/speech/dtw_aligner.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace lipsync::speech {
namespace {

// `seconds` of a tone whose pitch and loudness change every 100 ms, between pauses of `pause_s`.
PcmAudio varied_tones(double seconds, double pause_s) {
  PcmAudio audio;
  std::mt19937 random(28);
  std::uniform_real_distribution<double> pitch_hz(150.0, 2500.0);
  const auto pause = static_cast<std::size_t>(pause_s * kFeatureRateHz);
  audio.samples.assign(pause, 0);
  double frequency = pitch_hz(random), phase = 0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(seconds * kFeatureRateHz); ++i) {
    if (i % 1600 == 0) frequency = pitch_hz(random);
    phase += 2 * std::numbers::pi * frequency / kFeatureRateHz;
    audio.samples.push_back(static_cast<std::int16_t>(8000 * std::sin(phase) + 2000 * std::sin(3.1 * phase)));
  }
  audio.samples.resize(audio.samples.size() + pause, 0);
  return audio;
}

// `audio` with `pause_s` of silence put in at `at_s`.
PcmAudio with_pause(const PcmAudio& audio, double at_s, double pause_s) {
  PcmAudio result = audio;
  const auto at = static_cast<std::ptrdiff_t>(at_s * kFeatureRateHz);
  result.samples.insert(result.samples.begin() + at, static_cast<std::size_t>(pause_s * kFeatureRateHz), 0);
  return result;
}

// One phone per 100 ms tone of varied_tones(seconds, pause_s), between two pauses.
std::vector<LabeledInterval> tone_phones(double seconds, double pause_s) {
  const auto pause_us = static_cast<std::int64_t>(pause_s * 1e6);
  const auto tones = static_cast<std::int64_t>(std::llround(seconds * 10));
  std::vector<LabeledInterval> phones{{"", 0, pause_us, 0}};
  for (std::int64_t k = 0; k < tones; ++k) {
    phones.push_back({"a", pause_us + k * 100'000, pause_us + (k + 1) * 100'000, 0});
  }
  phones.push_back({"", pause_us + tones * 100'000, 2 * pause_us + tones * 100'000, 0});
  return phones;
}

// tone_phones(2.0, 0.3) with a pause of 300 ms put in at 1.3 s (as with_pause does to the audio):
// the phones from there on move by it.
std::vector<LabeledInterval> tone_phones_with_pause_at_1_3_s() {
  std::vector<LabeledInterval> phones = tone_phones(2.0, 0.3);
  for (std::size_t k = 11; k < phones.size(); ++k) {
    phones[k].start_us += 300'000;
    phones[k].end_us += 300'000;
  }
  phones.insert(phones.begin() + 11, LabeledInterval{"", 1'300'000, 1'600'000, 0});
  phones[10].end_us = 1'300'000;
  return phones;
}

FeatureFrames stretched(const FeatureFrames& frames, int factor) {
  FeatureFrames result;
  result.dimensions = frames.dimensions;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    for (int copy = 0; copy < factor; ++copy) {
      result.values.insert(result.values.end(), frames.frame(k), frames.frame(k) + frames.dimensions);
      result.level_db.push_back(frames.level_db[k]);
    }
  }
  return result;
}

TEST(AcousticFeatures, OneFrameEvery10MsWithEveryDimensionOfMeanZero) {
  const PcmAudio audio = varied_tones(2.0, 0.3);
  const FeatureFrames frames = mfcc_features(audio);
  EXPECT_EQ(frames.dimensions, 26);
  EXPECT_EQ(frames.size(), 1 + (audio.samples.size() - 400) / 160);
  for (int d = 0; d < frames.dimensions; ++d) {
    double sum = 0;
    for (std::size_t k = 0; k < frames.size(); ++k) sum += frames.frame(k)[d];
    EXPECT_NEAR(sum / double(frames.size()), 0.0, 1e-3) << "dimension " << d;
  }
  EXPECT_EQ(mfcc_features(PcmAudio{kFeatureRateHz, std::vector<std::int16_t>(399, 0)}).size(), 0U);
}

TEST(AcousticFeatures, SpeechIsFoundBetweenThePauses) {
  const FeatureFrames frames = mfcc_features(varied_tones(2.0, 0.3));
  const auto [first, last] = speech_frames(frames);
  EXPECT_NEAR(double(first), 28.0, 3.0);  // the first window reaching into the tone, 300 ms − 25 ms
  EXPECT_NEAR(double(last), 230.0, 3.0);  // the last window starting within it, 2.3 s
}

TEST(DtwWarp, ASequenceWarpedToItselfStaysOnTheDiagonal) {
  const FeatureFrames frames = mfcc_features(varied_tones(2.0, 0.3));
  const WarpPath path = warp(frames, frames, 50, speech_frames(frames), speech_frames(frames));
  ASSERT_EQ(path.first.size(), frames.size());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    EXPECT_EQ(path.first[k], k);
    EXPECT_EQ(path.last[k], k);
  }
  EXPECT_NEAR(path.mean_distance, 0.0, 1e-9);
  EXPECT_GT(path.unrelated_distance, 1.0);
  EXPECT_EQ(carry_time_us(path, 123'456), 123'456);
}

TEST(DtwWarp, BoundariesCarriedAcrossAUniformStretchDoubleTheirTimes) {
  const FeatureFrames frames = mfcc_features(varied_tones(2.0, 0.3));
  const FeatureFrames twice = stretched(frames, 2);
  const WarpPath path = warp(frames, twice, 500, speech_frames(frames), speech_frames(twice));
  for (const std::int64_t t_us : {400'000, 800'000, 1'500'000, 2'000'000}) {
    // Frame k of `frames` is frames 2k and 2k+1 of `twice`: time t lands at about 2t.
    EXPECT_NEAR(double(carry_time_us(path, t_us)), 2.0 * double(t_us), 25'000.0) << t_us;
  }
}

TEST(DtwWarp, ANarrowBandStillReachesTheFarCorner) {
  const FeatureFrames frames = mfcc_features(varied_tones(1.0, 0.1));
  const FeatureFrames thrice = stretched(frames, 3);
  const WarpPath path = warp(frames, thrice, 1, {0, frames.size() - 1}, {0, thrice.size() - 1});
  ASSERT_EQ(path.last.size(), frames.size());
  EXPECT_EQ(path.first.front(), 0U);
  EXPECT_EQ(path.last.back(), thrice.size() - 1);
  for (std::size_t k = 1; k < frames.size(); ++k) EXPECT_GE(path.first[k], path.last[k - 1]) << k;
}

// Frames of one dimension, all at speech level: `runs` of (value, count).
FeatureFrames level_frames(std::initializer_list<std::pair<float, int>> runs) {
  FeatureFrames frames;
  frames.dimensions = 1;
  for (const auto& [value, count] : runs) {
    frames.values.insert(frames.values.end(), static_cast<std::size_t>(count), value);
    frames.level_db.insert(frames.level_db.end(), static_cast<std::size_t>(count), -20.0);
  }
  return frames;
}

TEST(DtwWarp, AFrameALittleCloserDoesNotTakeAWholeStretch) {
  // The shape of Finnish "aamulla": the rendering's vowel (6 frames) then a nasal whose first frame
  // lies a little nearer the recording's vowel (30 frames; distance 15) than the rendering's vowel does
  // (21), the nasal's other frames (its release) far from both.
  const FeatureFrames rendering = level_frames({{0, 3}, {60, 6}, {96, 1}, {130, 2}, {180, 3}});
  const FeatureFrames recording = level_frames({{0, 3}, {81, 30}, {96, 1}, {130, 2}, {180, 3}});
  const auto nasal_start_us = [&](const StretchCost& stretch) {
    const WarpPath path = warp(rendering, recording, 50, speech_frames(rendering), speech_frames(recording), stretch);
    return carry_time_us(path, feature_frame_centre_us(8) + kFeatureHopUs / 2);  // between frames 8 and 9
  };
  // Between the recording's frames 32 and 33, where its nasal starts.
  const std::int64_t recording_nasal_us = feature_frame_centre_us(32) + kFeatureHopUs / 2;
  // The nasal's first frame takes no more of the vowel than a run is free for (8 frames), ...
  const std::int64_t charged_us = nasal_start_us(StretchCost{});
  EXPECT_GE(charged_us, recording_nasal_us - 8 * kFeatureHopUs);
  EXPECT_LE(charged_us, recording_nasal_us);
  // ... where with runs free it takes all of it but the frame the rendering's vowel is squeezed onto.
  EXPECT_EQ(nasal_start_us(StretchCost{.free_frames = 8, .cost = 0}), feature_frame_centre_us(3) + kFeatureHopUs / 2);
}

TEST(MissingPauses, APauseOnlyTheRecordingHasIsPutBeforeThePhoneItPrecedes) {
  const PcmAudio rendering_audio = varied_tones(2.0, 0.3);
  const FeatureFrames rendering = mfcc_features(rendering_audio);
  const FeatureFrames recording = mfcc_features(with_pause(rendering_audio, 1.3, 0.3));
  const WarpPath path = warp(rendering, recording, 100, speech_frames(rendering), speech_frames(recording));
  const std::vector<LabeledInterval> phones = tone_phones(2.0, 0.3);
  const std::vector<MissingPause> pauses = missing_pauses(path, rendering, phones, recording);
  ASSERT_EQ(pauses.size(), 1U);
  EXPECT_EQ(phones[pauses[0].phone].start_us, 1'300'000);
  EXPECT_NEAR(double(pauses[0].duration_us), 300'000.0, 40'000.0);
}

TEST(MissingPauses, NoneWhereTheRenderingHasThePausesOrTheyAreShort) {
  const PcmAudio rendering_audio = with_pause(varied_tones(2.0, 0.3), 1.3, 0.3);
  const FeatureFrames rendering = mfcc_features(rendering_audio);
  const FeatureFrames same = mfcc_features(rendering_audio);
  const std::vector<LabeledInterval> phones = tone_phones_with_pause_at_1_3_s();
  EXPECT_THAT(missing_pauses(warp(rendering, same, 100, speech_frames(rendering), speech_frames(same)), rendering,
                             phones, same),
              ::testing::IsEmpty());
  const FeatureFrames plain = mfcc_features(varied_tones(2.0, 0.3));
  const FeatureFrames short_pause = mfcc_features(with_pause(varied_tones(2.0, 0.3), 1.3, 0.08));
  EXPECT_THAT(missing_pauses(warp(plain, short_pause, 100, speech_frames(plain), speech_frames(short_pause)), plain,
                             tone_phones(2.0, 0.3), short_pause),
              ::testing::IsEmpty());
}

TEST(ExtraPauses, APauseOnlyTheRenderingHasIsCutAndOneBothHaveIsKept) {
  const PcmAudio paused_audio = with_pause(varied_tones(2.0, 0.3), 1.3, 0.3);
  const FeatureFrames paused = mfcc_features(paused_audio);
  const std::vector<LabeledInterval> phones = tone_phones_with_pause_at_1_3_s();
  const FeatureFrames plain = mfcc_features(varied_tones(2.0, 0.3));
  const std::vector<ExtraPause> cuts =
      extra_pauses(warp(paused, plain, 100, speech_frames(paused), speech_frames(plain)), paused, phones, plain);
  ASSERT_EQ(cuts.size(), 1U);
  EXPECT_EQ(cuts[0].first_phone, 11U);
  EXPECT_EQ(cuts[0].last_phone, 11U);
  EXPECT_NEAR(double(cuts[0].duration_us), 290'000.0, 40'000.0);
  EXPECT_THAT(
      extra_pauses(warp(paused, paused, 100, speech_frames(paused), speech_frames(paused)), paused, phones, paused),
      ::testing::IsEmpty());
}

// The formant band's level every ms (10 ms windows): `runs` of (dB, ms).
std::vector<double> level_ms(std::initializer_list<std::pair<double, int>> runs) {
  std::vector<double> level;
  for (const auto& [db, ms] : runs) level.insert(level.end(), static_cast<std::size_t>(ms), db);
  return level;
}

TEST(BilabialNasals, AnMCarriedIntoTheLoudVowelBeforeItStartsWhereTheLevelFallsToItsMurmur) {
  // Russian "в большом" /o m/: the vowel loud to 400 ms, the murmur 10 dB under it to 500 ms, and
  // the warp's /m/ starting at 300 ms, inside the vowel.
  const std::vector<LabeledInterval> phones{
      {"", 0, 0, 0}, {"o", 0, 0, 0}, {"m", 0, 0, 0}, {"a", 0, 0, 0}, {"", 0, 0, 0}};
  const std::vector<double> level = level_ms({{-60, 100}, {-16, 300}, {-26, 100}, {-16, 200}, {-60, 100}});
  std::vector<std::int64_t> bounds{0, 100'000, 300'000, 500'000, 700'000, 800'000};
  start_bilabial_nasals_at_murmur(bounds, phones, level);
  EXPECT_EQ(bounds[2], 400'000);
  EXPECT_EQ(bounds[3], 500'000);

  // Started at a falling level already (the murmur comes on slowly), it stays; so does /n/.
  const std::vector<double> falling = level_ms({{-60, 100}, {-16, 200}, {-20, 10}, {-23, 10}, {-26, 280}, {-60, 200}});
  bounds = {0, 100'000, 300'000, 500'000, 700'000, 800'000};
  start_bilabial_nasals_at_murmur(bounds, phones, falling);
  EXPECT_EQ(bounds[2], 300'000);
  std::vector<LabeledInterval> n_phones = phones;
  n_phones[2].label = "n";
  bounds = {0, 100'000, 300'000, 500'000, 700'000, 800'000};
  start_bilabial_nasals_at_murmur(bounds, n_phones, level);
  EXPECT_EQ(bounds[2], 300'000);
}

// Made-up speech at 16 kHz, one part after another: a vowel (the harmonics of 120 Hz up to 3.5 kHz,
// loud in the formant band and below 400 Hz), a voiced closure (the 120 Hz fundamental alone: the
// voicing bar), or silence (a voiceless closure or pause), each `seconds` long, each sound rising over
// its first 10 ms (an abrupt start would click across the bands).
enum class Part { kVowel, kVoicingBar, kSilence };
PcmAudio made_up_speech(std::initializer_list<std::pair<Part, double>> parts) {
  PcmAudio audio;
  double t = 0;
  for (const auto& [part, seconds] : parts) {
    for (std::size_t i = 0; i < static_cast<std::size_t>(seconds * kFeatureRateHz); ++i, t += 1.0 / kFeatureRateHz) {
      const double rise = std::min(1.0, double(i) / (0.01 * kFeatureRateHz));
      double value = 0;
      if (part == Part::kVowel) {
        for (int harmonic = 1; harmonic * 120 <= 3500; ++harmonic) {
          value += 1500 / std::sqrt(double(harmonic)) * std::sin(2 * std::numbers::pi * 120 * harmonic * t);
        }
      } else if (part == Part::kVoicingBar) {
        value = 1500 * std::sin(2 * std::numbers::pi * 120 * t);
      }
      audio.samples.push_back(static_cast<std::int16_t>(std::clamp(rise * value, -32000.0, 32000.0)));
    }
  }
  return audio;
}

// The start of each phone of `labels` (its first a pause from 0), and the end of the last.
std::pair<std::vector<LabeledInterval>, std::vector<std::int64_t>> phones_from(
    std::initializer_list<std::pair<const char*, std::int64_t>> labels, std::int64_t end_us) {
  std::vector<LabeledInterval> phones;
  std::vector<std::int64_t> bounds;
  for (const auto& [label, start_us] : labels) {
    if (!phones.empty()) phones.back().end_us = start_us;
    phones.push_back({label, start_us, end_us, 0});
    bounds.push_back(start_us);
  }
  bounds.push_back(end_us);
  return {phones, bounds};
}

TEST(VoicedBilabialClosures, ABStartsWhereItsVoicedClosureBeginsWithThePhonesInsideItSqueezedBefore) {
  // "molt bo" as Festival's Catalan says it, [o l b o], closing at 0.70 s; espeak-ng's [o l t β o]
  // carried with its /l t/ inside the closure and its /β/ at the burst.
  const PcmAudio speech = made_up_speech({{Part::kSilence, 0.3},
                                          {Part::kVowel, 0.4},
                                          {Part::kVoicingBar, 0.08},
                                          {Part::kVowel, 0.3},
                                          {Part::kSilence, 0.3}});
  auto [phones, bounds] = phones_from(
      {{"", 0}, {"o", 300'000}, {"l", 705'000}, {"t", 730'000}, {"β", 770'000}, {"o", 785'000}, {"", 1'080'000}},
      1'380'000);
  start_voiced_bilabials_at_closures(bounds, phones, speech);
  EXPECT_NEAR(double(bounds[4]), 700'000.0, 12'000.0);
  EXPECT_EQ(bounds[3], bounds[4] - 10'000);
  EXPECT_EQ(bounds[2], bounds[3] - 10'000);
  EXPECT_EQ(bounds[1], 300'000);
  EXPECT_EQ(bounds[5], 785'000);

  // After a voiceless stop's silence ("barret blau": [t b], the /b/ voiced from 0.76 s), the /b/
  // starts where the voicing bar rises.
  const PcmAudio after_stop = made_up_speech({{Part::kSilence, 0.3},
                                              {Part::kVowel, 0.4},
                                              {Part::kSilence, 0.06},
                                              {Part::kVoicingBar, 0.06},
                                              {Part::kVowel, 0.3},
                                              {Part::kSilence, 0.3}});
  auto [stop_phones, stop_bounds] = phones_from(
      {{"", 0}, {"ɛ", 300'000}, {"t", 700'000}, {"β", 805'000}, {"l", 830'000}, {"", 1'120'000}}, 1'420'000);
  start_voiced_bilabials_at_closures(stop_bounds, stop_phones, after_stop);
  EXPECT_NEAR(double(stop_bounds[3]), 760'000.0, 10'000.0);
  EXPECT_EQ(stop_bounds[2], 700'000);
}

TEST(VoicedBilabialClosures, AVoicelessClosureOrAFricativeOrNasalBeforeTheBIsLeftAlone) {
  const auto unchanged = [](const PcmAudio& speech,
                            std::initializer_list<std::pair<const char*, std::int64_t>> labels) {
    auto [phones, bounds] = phones_from(labels, 1'380'000);
    const std::vector<std::int64_t> before = bounds;
    start_voiced_bilabials_at_closures(bounds, phones, speech);
    EXPECT_EQ(bounds, before);
  };
  const PcmAudio voiced = made_up_speech({{Part::kSilence, 0.3},
                                          {Part::kVowel, 0.4},
                                          {Part::kVoicingBar, 0.08},
                                          {Part::kVowel, 0.3},
                                          {Part::kSilence, 0.3}});
  const PcmAudio voiceless = made_up_speech(
      {{Part::kSilence, 0.3}, {Part::kVowel, 0.4}, {Part::kSilence, 0.08}, {Part::kVowel, 0.3}, {Part::kSilence, 0.3}});
  // A voiceless closure: a /p b/ after a stop shares its silence, and where the lips close is not heard.
  unchanged(voiceless, {{"", 0}, {"o", 300'000}, {"t", 705'000}, {"b", 770'000}, {"o", 785'000}, {"", 1'080'000}});
  // A voiced fricative or a nasal before the /b/ is low in the formant band and voiced, like the closure.
  unchanged(voiced, {{"", 0}, {"o", 300'000}, {"v", 705'000}, {"b", 770'000}, {"o", 785'000}, {"", 1'080'000}});
  unchanged(voiced, {{"", 0}, {"o", 300'000}, {"m", 705'000}, {"b", 770'000}, {"o", 785'000}, {"", 1'080'000}});
  // A /b/ carried to its closure's start already stays; a /p/ is not voiced.
  unchanged(voiced, {{"", 0}, {"o", 300'000}, {"p", 770'000}, {"o", 785'000}, {"", 1'080'000}});
}

}  // namespace
}  // namespace lipsync::speech
