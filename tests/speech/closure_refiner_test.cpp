// refine_closures on signals whose closures are known to the sample: a vowel-like
// harmonic sound, then a closure (silence, or a voicing bar below 400 Hz as in
// /b/, or a low murmur as in /m/), then a burst and the vowel again. The aligner's
// boundaries are put where PocketSphinx tends to put them (off by 10 to 30 ms);
// the refiner must find the true ones, leave other phones and signal-less
// boundaries alone, and keep the phones tiling the audio.
#include "lipsync/speech/closure_refiner.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

namespace lipsync {
namespace {

constexpr int kRate = 16000;

std::int64_t sample_of(std::int64_t us) { return us * kRate / 1'000'000; }

// A vowel: harmonics of 120 Hz shaped by formants at 700, 1200 and 2600 Hz.
double vowel(std::int64_t i) {
  double v = 0;
  for (int h = 1; h * 120 < 4000; ++h) {
    const double hz = h * 120.0;
    double gain = 0;
    for (const double formant : {700.0, 1200.0, 2600.0}) gain += 1.0 / (1.0 + std::pow((hz - formant) / 120.0, 2));
    v += gain * std::sin(2 * std::numbers::pi * hz * double(i) / kRate);
  }
  return 0.12 * v;
}

enum class Closure { silent, voiced, nasal };

// [0, close) vowel, [close, release) closure, a 5 ms burst, then vowel to `end`.
speech::PcmAudio stop(std::int64_t close_us, std::int64_t release_us, std::int64_t end_us, Closure kind) {
  speech::PcmAudio audio;
  std::mt19937 noise(7);
  std::normal_distribution<double> gauss(0, 0.1);
  for (std::int64_t i = 0; i < sample_of(end_us); ++i) {
    double v;
    if (i < sample_of(close_us) || i >= sample_of(release_us) + 80) {
      v = vowel(i);
    } else if (i >= sample_of(release_us)) {
      v = gauss(noise);
    } else {
      const double t = double(i) / kRate;
      v = kind == Closure::silent ? 0.0
          : kind == Closure::voiced
              ? 0.1 * std::sin(2 * std::numbers::pi * 120 * t)
              : 0.08 * std::sin(2 * std::numbers::pi * 250 * t) + 0.004 * std::sin(2 * std::numbers::pi * 2500 * t);
    }
    audio.samples.push_back(static_cast<std::int16_t>(std::lround(std::clamp(v, -1.0, 1.0) * 32767)));
  }
  return audio;
}

LabeledUtterance phones_of(std::vector<LabeledInterval> intervals) {
  LabeledUtterance utterance;
  utterance.phone_set = "arpabet";
  utterance.intervals = std::move(intervals);
  return utterance;
}

TEST(ClosureRefiner, StopClosureAndReleaseMoveToTheEnergySteps) {
  for (const auto& [kind, label] : {std::pair{Closure::silent, "P"}, {Closure::voiced, "B"}, {Closure::nasal, "M"}}) {
    const speech::PcmAudio audio = stop(300'000, 380'000, 700'000, kind);
    LabeledUtterance phones =
        phones_of({{"AA", 0, 320'000, 1}, {label, 320'000, 360'000, 2}, {"AA", 360'000, 700'000, 3}});
    speech::ClosureRefinerOptions exact;
    exact.closure_lead_us = 0;  // the energy step itself, not the onset and lead a natural closing gesture gets
    exact.closure_onset_fraction = 1.0;
    const std::vector<speech::RefinedBoundary> refined = speech::refine_closures(audio, phones, exact);
    ASSERT_EQ(refined.size(), 2U) << label;
    EXPECT_TRUE(refined[0].moved && refined[1].moved) << label;
    EXPECT_NEAR(double(phones.intervals[1].start_us), 300e3, 2e3) << label;
    EXPECT_NEAR(double(phones.intervals[1].end_us), 380e3, 2e3) << label;
    EXPECT_EQ(phones.intervals[0].end_us, phones.intervals[1].start_us) << label;
    EXPECT_EQ(phones.intervals[2].start_us, phones.intervals[1].end_us) << label;
    EXPECT_EQ(refined[0].aligned_us, 320'000);
    EXPECT_EQ(refined[1].aligned_us, 360'000);
    EXPECT_GE(refined[0].step_db, 12.0) << label << ": a closure is a clear step, well above min_step_db";
  }
}

TEST(ClosureRefiner, TheClosureIsPlacedItsLeadBeforeTheOnsetOfTheFall) {
  // A step at 300 ms into digital silence: the fall of the 10 ms means is still 40 % of
  // its peak (the default onset fraction) 3 ms before the step; the lead is 3 ms more.
  const speech::PcmAudio audio = stop(300'000, 380'000, 700'000, Closure::silent);
  LabeledUtterance phones = phones_of({{"AA", 0, 320'000, 1}, {"P", 320'000, 360'000, 2}, {"AA", 360'000, 700'000, 3}});
  const std::vector<speech::RefinedBoundary> refined = speech::refine_closures(audio, phones);
  ASSERT_EQ(refined.size(), 2U);
  EXPECT_NEAR(double(phones.intervals[1].start_us), 294e3, 2e3);
  EXPECT_NEAR(double(phones.intervals[1].end_us), 380e3, 2e3);
}

TEST(ClosureRefiner, AnMWhoseFormantsBarelyFallClosesWhereItsMurmurBegins) {
  // As in espeak-ng's "lemons": into the /m/ at 300 ms the vowel's formants fall by
  // under 10 dB, too little to move a boundary, while a murmur at 150 Hz rises below
  // them; the formant band's level less the level below 400 Hz falls by more.
  speech::PcmAudio audio;
  for (std::int64_t i = 0; i < sample_of(600'000); ++i) {
    const bool murmur = i >= sample_of(300'000) && i < sample_of(400'000);
    const double v =
        murmur ? 0.5 * vowel(i) + 0.3 * std::sin(2 * std::numbers::pi * 150 * double(i) / kRate) : vowel(i);
    audio.samples.push_back(static_cast<std::int16_t>(std::lround(std::clamp(v, -1.0, 1.0) * 32767)));
  }
  LabeledUtterance phones = phones_of({{"AA", 0, 320'000, 1}, {"M", 320'000, 400'000, 2}, {"AA", 400'000, 600'000, 3}});
  const std::vector<speech::RefinedBoundary> refined = speech::refine_closures(audio, phones);
  ASSERT_EQ(refined.size(), 2U);
  EXPECT_TRUE(refined[0].moved);
  EXPECT_GE(refined[0].step_db, 10.0);
  EXPECT_NEAR(double(phones.intervals[1].start_us), 300e3, 2e3);  // the contrast's steepest fall
  EXPECT_EQ(phones.intervals[0].end_us, phones.intervals[1].start_us);
  // The same /m/ as a /b/: no murmur rule, and the formant band's step is too small.
  phones = phones_of({{"AA", 0, 320'000, 1}, {"B", 320'000, 400'000, 2}, {"AA", 400'000, 600'000, 3}});
  const std::vector<speech::RefinedBoundary> as_b = speech::refine_closures(audio, phones);
  ASSERT_EQ(as_b.size(), 2U);
  EXPECT_FALSE(as_b[0].moved);
  EXPECT_LT(as_b[0].step_db, 10.0);
  EXPECT_EQ(phones.intervals[1].start_us, 320'000);
}

TEST(ClosureRefiner, BoundariesStayWhereTheSignalShowsNoStep) {
  speech::PcmAudio audio;
  for (std::int64_t i = 0; i < sample_of(600'000); ++i)
    audio.samples.push_back(static_cast<std::int16_t>(std::lround(vowel(i) * 32767)));
  const LabeledUtterance aligned =
      phones_of({{"AA", 0, 200'000, 1}, {"M", 200'000, 280'000, 2}, {"AA", 280'000, 600'000, 3}});
  LabeledUtterance phones = aligned;
  const std::vector<speech::RefinedBoundary> refined = speech::refine_closures(audio, phones);
  ASSERT_EQ(refined.size(), 2U);
  EXPECT_FALSE(refined[0].moved);
  EXPECT_FALSE(refined[1].moved);
  EXPECT_LT(refined[0].step_db, 3.0);
  EXPECT_EQ(phones.intervals[1].start_us, 200'000);
  EXPECT_EQ(phones.intervals[1].end_us, 280'000);
}

TEST(ClosureRefiner, OnlyLipPhonesMoveAndOnlyWithinTheSearchWindow) {
  const speech::PcmAudio audio = stop(300'000, 380'000, 700'000, Closure::silent);
  // /t/ on the same closure: not a lip phone, so untouched.
  LabeledUtterance phones = phones_of({{"AA", 0, 320'000, 1}, {"T", 320'000, 360'000, 2}, {"AA", 360'000, 700'000, 3}});
  EXPECT_TRUE(speech::refine_closures(audio, phones).empty());
  EXPECT_EQ(phones.intervals[1].start_us, 320'000);
  // A /p/ placed 60 ms after the true closure, with a 40 ms window: the true step is out of reach.
  phones = phones_of({{"AA", 0, 360'000, 1}, {"P", 360'000, 440'000, 2}, {"AA", 440'000, 700'000, 3}});
  speech::ClosureRefinerOptions narrow;
  narrow.search_us = 40'000;
  speech::refine_closures(audio, phones, narrow);
  EXPECT_GE(phones.intervals[1].start_us, 320'000);
  EXPECT_TRUE(speech::is_lip_phone("b") && speech::is_lip_phone("M1") && speech::is_lip_phone("F") &&
              speech::is_lip_phone("v"));
  EXPECT_FALSE(speech::is_lip_phone("") || speech::is_lip_phone("TH") || speech::is_lip_phone("AA"));
}

TEST(ClosureRefiner, PhonesKeepTheirOrderAndMinimumLength) {
  const speech::PcmAudio audio = stop(300'000, 380'000, 700'000, Closure::silent);
  // A /p/ of 20 ms squeezed between short neighbours: nothing may collapse or cross.
  LabeledUtterance phones = phones_of({{"", 0, 290'000, 1},
                                       {"AA", 290'000, 305'000, 2},
                                       {"P", 305'000, 325'000, 3},
                                       {"M", 325'000, 340'000, 4},
                                       {"AA", 340'000, 700'000, 5}});
  speech::refine_closures(audio, phones);
  for (std::size_t i = 0; i < phones.intervals.size(); ++i) {
    EXPECT_GE(phones.intervals[i].end_us - phones.intervals[i].start_us, 10'000) << i;
    if (i > 0) {
      EXPECT_EQ(phones.intervals[i].start_us, phones.intervals[i - 1].end_us) << i;
    }
  }
  EXPECT_EQ(phones.intervals.back().end_us, 700'000);
}

// Sounds one after another: each (kind, end µs) runs from the previous end.
enum class Sound { vowel, silence, murmur };
speech::PcmAudio sounds(std::initializer_list<std::pair<Sound, std::int64_t>> parts) {
  speech::PcmAudio audio;
  for (const auto& [kind, end_us] : parts) {
    for (auto i = static_cast<std::int64_t>(audio.samples.size()); i < sample_of(end_us); ++i) {
      const double t = double(i) / kRate;
      const double v = kind == Sound::vowel     ? vowel(i)
                       : kind == Sound::silence ? 0.0
                                                : 0.08 * std::sin(2 * std::numbers::pi * 250 * t) +
                                                      0.004 * std::sin(2 * std::numbers::pi * 2500 * t);
      audio.samples.push_back(static_cast<std::int16_t>(std::lround(v * 32767)));
    }
  }
  return audio;
}

// The recogniser's phones for a vowel, a `stop` from 200 ms, a pause from 230 ms over its release
// and the next closure, and a `bilabial` from `bilabial_us` (30 ms) before a vowel to `end_us`.
LabeledUtterance stop_pause_bilabial(const char* stop, std::int64_t bilabial_us, const char* bilabial,
                                     std::int64_t end_us) {
  return phones_of({{"AA", 0, 200'000, 1},
                    {stop, 200'000, 230'000, 2},
                    {"", 230'000, bilabial_us, 3},
                    {bilabial, bilabial_us, bilabial_us + 30'000, 4},
                    {"AA", bilabial_us + 30'000, end_us, 5}});
}

// A vowel to 200 ms, a stop's closure to 260 ms, its release to 300 ms, a second stop's closure to
// 380 ms, a vowel to 700 ms.
speech::PcmAudio two_stop_closures() {
  return sounds({{Sound::vowel, 200'000},
                 {Sound::silence, 260'000},
                 {Sound::vowel, 300'000},
                 {Sound::silence, 380'000},
                 {Sound::vowel, 700'000}});
}

TEST(ClosureRefiner, AShortPauseBeforeAStopIsTakenForItsClosure) {
  // The recogniser heard a /p/'s silent closure (300 to 380 ms) as a pause and put
  // the /p/ at its burst: the /p/ takes the pause over and starts at the closure.
  const speech::PcmAudio audio = stop(300'000, 380'000, 700'000, Closure::silent);
  LabeledUtterance phones = phones_of(
      {{"AA", 0, 310'000, 1}, {"", 310'000, 370'000, 2}, {"P", 370'000, 390'000, 3}, {"AA", 390'000, 700'000, 4}});
  const std::vector<speech::RefinedBoundary> refined = speech::refine_closures(audio, phones);
  ASSERT_EQ(phones.intervals.size(), 3U) << "the pause is gone";
  EXPECT_EQ(phones.intervals[1].label, "P");
  EXPECT_NEAR(double(phones.intervals[1].start_us), 294e3, 2e3) << "the closure, its lead before the fall";
  EXPECT_EQ(phones.intervals[0].end_us, phones.intervals[1].start_us);
  ASSERT_FALSE(refined.empty());
  EXPECT_EQ(refined[0].phone, 1U);
  EXPECT_TRUE(refined[0].moved);
  // A long pause (over longest_closure_pause_us) stays a pause.
  phones = phones_of(
      {{"AA", 0, 100'000, 1}, {"", 100'000, 370'000, 2}, {"P", 370'000, 390'000, 3}, {"AA", 390'000, 700'000, 4}});
  speech::refine_closures(audio, phones);
  EXPECT_EQ(phones.intervals.size(), 4U);
}

TEST(ClosureRefiner, AShortPauseAfterAStopIsTakenForTheRestOfItsClosure) {
  // The recogniser put a /p/ on the closing transition (270 to 300 ms) and heard the rest of its
  // silent closure (300 to 380 ms) as a pause up to the burst, as in espeak-ng's "Wipe the": the /p/
  // takes the pause over, starts at the closure and ends at the burst.
  const speech::PcmAudio audio = stop(300'000, 380'000, 700'000, Closure::silent);
  LabeledUtterance phones = phones_of(
      {{"AA", 0, 270'000, 1}, {"P", 270'000, 300'000, 2}, {"", 300'000, 375'000, 3}, {"AA", 375'000, 700'000, 4}});
  speech::refine_closures(audio, phones);
  ASSERT_EQ(phones.intervals.size(), 3U) << "the pause is gone";
  EXPECT_EQ(phones.intervals[1].label, "P");
  EXPECT_NEAR(double(phones.intervals[1].start_us), 294e3, 2e3) << "the closure, its lead before the fall";
  EXPECT_NEAR(double(phones.intervals[1].end_us), 380e3, 2e3) << "the burst";
  EXPECT_EQ(phones.intervals[2].start_us, phones.intervals[1].end_us);
  // A long pause (over longest_closure_pause_us), or one that ends the utterance, stays a pause.
  for (const std::int64_t pause_end : {480'000, 700'000}) {
    std::vector<LabeledInterval> intervals = {
        {"AA", 0, 270'000, 1}, {"P", 270'000, 300'000, 2}, {"", 300'000, pause_end, 3}};
    if (pause_end < 700'000) intervals.push_back({"AA", pause_end, 700'000, 4});
    phones = phones_of(intervals);
    speech::refine_closures(audio, phones);
    EXPECT_EQ(phones.intervals.size(), intervals.size()) << pause_end;
    EXPECT_TRUE(phones.intervals[2].label.empty()) << pause_end;
  }
}

TEST(ClosureRefiner, APauseBetweenTwoStopsGivesTheSecondItsClosureAtTheLastFall) {
  // /k/ closure 200 to 260 ms, its release 260 to 300 ms, then the /p/'s closure 300 to
  // 380 ms: the pause the recogniser put over both ends where the /p/'s closure starts.
  const speech::PcmAudio audio = two_stop_closures();
  LabeledUtterance phones = stop_pause_bilabial("K", 370'000, "P", 700'000);
  speech::refine_closures(audio, phones);
  ASSERT_EQ(phones.intervals.size(), 5U);
  EXPECT_NEAR(double(phones.intervals[3].start_us), 294e3, 2e3);
  EXPECT_EQ(phones.intervals[2].end_us, phones.intervals[3].start_us);
  EXPECT_EQ(phones.intervals[2].start_us, 230'000) << "the /k/ keeps its place";
}

TEST(ClosureRefiner, APAfterAReleasedStopStartsAtTheLastFallAndAfterAnUnreleasedOneStays) {
  // /t/ closure 200 to 260 ms, its release 260 to 300 ms, then the /p/'s closure 300 to 380 ms,
  // no pause between: the aligner put the /p/ inside the /t/'s closure, before its release.
  const speech::PcmAudio released = two_stop_closures();
  const auto t_p = [] {
    return phones_of(
        {{"AA", 0, 200'000, 1}, {"T", 200'000, 240'000, 2}, {"P", 240'000, 390'000, 3}, {"AA", 390'000, 700'000, 4}});
  };
  LabeledUtterance phones = t_p();
  speech::refine_closures(released, phones);
  EXPECT_NEAR(double(phones.intervals[2].start_us), 294e3, 2e3);
  EXPECT_EQ(phones.intervals[1].end_us, phones.intervals[2].start_us);
  // One silence 200 to 380 ms (no release of the /t/ heard): where the lips close in it is not
  // heard, and the /p/ stays where it was put.
  const speech::PcmAudio unreleased =
      sounds({{Sound::vowel, 200'000}, {Sound::silence, 380'000}, {Sound::vowel, 700'000}});
  phones = t_p();
  speech::refine_closures(unreleased, phones);
  EXPECT_EQ(phones.intervals[2].start_us, 240'000);
}

TEST(ClosureRefiner, APauseAfterAStopHoldsBothClosuresAndWithNoReleaseHeardIsHalved) {
  // /tʃ/ closure 200 to 260 ms, its frication 260 to 330 ms, the /p/'s closure 330 to 500 ms:
  // the recogniser's pause over the frication and the /p/'s closure (260 ms) is longer than
  // longest_closure_pause_us, but after a stop it may hold both closures, so the /p/ still
  // starts at its last fall.
  const speech::PcmAudio frication = sounds({{Sound::vowel, 200'000},
                                             {Sound::silence, 260'000},
                                             {Sound::vowel, 330'000},
                                             {Sound::silence, 500'000},
                                             {Sound::vowel, 800'000}});
  LabeledUtterance phones = stop_pause_bilabial("CH", 490'000, "P", 800'000);
  speech::refine_closures(frication, phones);
  ASSERT_EQ(phones.intervals.size(), 5U);
  EXPECT_NEAR(double(phones.intervals[3].start_us), 324e3, 2e3);
  // One silence 200 to 380 ms, the /t/'s release not heard: where the lips close in it is not
  // heard, and the /b/ takes its second half, from the middle of the /t/'s start and its burst.
  const speech::PcmAudio unreleased =
      sounds({{Sound::vowel, 200'000}, {Sound::silence, 380'000}, {Sound::vowel, 700'000}});
  phones = stop_pause_bilabial("T", 370'000, "B", 700'000);
  const std::vector<speech::RefinedBoundary> refined = speech::refine_closures(unreleased, phones);
  ASSERT_EQ(phones.intervals.size(), 5U);
  EXPECT_EQ(phones.intervals[3].start_us, 285'000);
  EXPECT_EQ(phones.intervals[2].end_us, 285'000);
  ASSERT_FALSE(refined.empty());
  EXPECT_TRUE(refined[0].moved);
}

TEST(ClosureRefiner, AnMAfterAPauseStartsWhereItsMurmurDoes) {
  const speech::PcmAudio audio = sounds({{Sound::silence, 200'000}, {Sound::murmur, 280'000}, {Sound::vowel, 600'000}});
  LabeledUtterance phones = phones_of({{"", 0, 220'000, 1}, {"M", 220'000, 290'000, 2}, {"AA", 290'000, 600'000, 3}});
  const std::vector<speech::RefinedBoundary> refined = speech::refine_closures(audio, phones);
  ASSERT_FALSE(refined.empty());
  EXPECT_TRUE(refined[0].moved);
  EXPECT_NEAR(double(phones.intervals[1].start_us), 200e3, 2e3) << "no lead: nothing closes after a pause";
  EXPECT_NEAR(double(phones.intervals[1].end_us), 280e3, 2e3);
}

TEST(ClosureRefiner, FormantBandLevelsFallInAClosure) {
  const speech::PcmAudio audio = stop(300'000, 380'000, 700'000, Closure::voiced);
  const std::vector<double> levels = speech::formant_band_levels_db(audio, 10'000, 10'000);
  ASSERT_EQ(levels.size(), 70U);
  EXPECT_GT(levels[10] - levels[34], 20.0) << "a /b/ closure keeps only its voicing bar below 400 Hz";
}

}  // namespace
}  // namespace lipsync
