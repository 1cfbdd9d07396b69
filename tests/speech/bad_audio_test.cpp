// Recorded speech that is not what the aligner hopes for: noise, clipped speech,
// 8 kHz telephone speech, a transcript of other words. Each gives an alignment
// or an InputError naming the source and what is wrong, in bounded time (the
// aligner refuses audio over 120 s before decoding: speech_test). The inputs are
// made here from espeak-ng speech and a fixed-seed generator; nothing large is
// committed.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <random>

#include "../support/input_error_text.hpp"
#include "lipsync/error.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/synthesizer.hpp"

namespace lipsync {
namespace {

using ::testing::HasSubstr;

constexpr const char* kText = "Papa parked the car.";

using testing::error_of;

std::vector<std::string> words_of(const speech::Alignment& alignment) {
  std::vector<std::string> words;
  for (const LabeledInterval& word : alignment.words) words.push_back(word.label);
  return words;
}

const speech::Synthesis& papa() {
  static const speech::Synthesis speech = speech::synthesize(kText);
  return speech;
}

speech::AlignmentOptions with_text(const char* text = kText) {
  speech::AlignmentOptions options;
  options.transcript = text;
  return options;
}

TEST(BadAudio, LoudNoiseDoesNotMatchATranscriptAndGivesNoBilabialsWithoutOne) {
  speech::PcmAudio noise;
  std::mt19937 generator(29);
  std::normal_distribution<double> gauss(0, 3000);
  for (int i = 0; i < 3 * 16000; ++i)
    noise.samples.push_back(static_cast<std::int16_t>(std::clamp(gauss(generator), -32768.0, 32767.0)));
  EXPECT_THAT(error_of([&] { speech::align_speech(noise, "noise.wav", with_text()); }),
              HasSubstr("noise.wav: the transcript does not match the audio"));
  const auto start = std::chrono::steady_clock::now();
  const speech::Alignment recognised = speech::align_speech(noise, "noise.wav", {});
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(30));
  EXPECT_EQ(recognised.phones.intervals.back().end_us, 3'000'000);
  // Steady noise has no energy steps: no lip boundary moves on it.
  EXPECT_TRUE(std::none_of(recognised.refined.begin(), recognised.refined.end(),
                           [](const speech::RefinedBoundary& boundary) { return boundary.moved; }));
}

speech::PcmAudio amplified(int gain) {
  speech::PcmAudio clipped = papa().audio;
  for (std::int16_t& sample : clipped.samples)
    sample = static_cast<std::int16_t>(std::clamp(sample * gain, -32768, 32767));
  return clipped;
}

TEST(BadAudio, ClippedSpeechAlignsWithANote) {
  const speech::PcmAudio clipped = amplified(8);
  const speech::Alignment aligned = speech::align_speech(clipped, "loud.wav", with_text());
  EXPECT_THAT(words_of(aligned), ::testing::ElementsAre("papa", "parked", "the", "car"));
  EXPECT_THAT(aligned.notes, ::testing::Contains(HasSubstr("of the samples are clipped")));
  EXPECT_TRUE(std::none_of(speech::align_speech(papa().audio, "papa.wav", with_text()).notes.begin(),
                           speech::align_speech(papa().audio, "papa.wav", with_text()).notes.end(),
                           [](const std::string& note) { return note.find("clipped") != std::string::npos; }));
}

TEST(BadAudio, SpeechClippedBeyondRecognitionIsRefusedSayingSo) {
  EXPECT_THAT(error_of([&] { speech::align_speech(amplified(40), "blown.wav", with_text()); }),
              ::testing::AllOf(HasSubstr("blown.wav: the transcript does not match the audio"),
                               HasSubstr("of the samples are clipped at full scale, which drowns its quiet parts")));
}

TEST(BadAudio, TelephoneSpeechAt8KhzAlignsAndItsClosuresAreRefined) {
  const speech::PcmAudio telephone = speech::resample(papa().audio, 8000);
  const speech::Alignment aligned = speech::align_speech(telephone, "phone.wav", with_text());
  EXPECT_THAT(words_of(aligned), ::testing::ElementsAre("papa", "parked", "the", "car"));
  EXPECT_THAT(aligned.notes, ::testing::Contains(std::string("resampled from 8000 Hz to 16000 Hz")));
  const auto moved = std::count_if(aligned.refined.begin(), aligned.refined.end(),
                                   [](const speech::RefinedBoundary& boundary) { return boundary.moved; });
  EXPECT_GE(moved, 3) << "the three /p/ closures of 'Papa parked' are plain in the band up to 3.5 kHz";
}

TEST(BadAudio, ATranscriptOfOtherWordsIsRefusedNamingTheFile) {
  EXPECT_THAT(error_of([&] { speech::align_speech(papa().audio, "papa.wav", with_text("Seven fish swim slowly.")); }),
              HasSubstr("papa.wav: the transcript does not match the audio"));
}

}  // namespace
}  // namespace lipsync
