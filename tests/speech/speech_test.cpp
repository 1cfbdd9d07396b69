// lipsync::speech on real espeak-ng, real PocketSphinx and real WAV bytes: text
// to timed phonemes (and where each word starts) to a track, the WAV reader's
// conversions and refusals, and the aligner's accuracy and its answers to bad
// input (silence, too long, a transcript that does not fit, a word the
// dictionary lacks).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <optional>
#include <sstream>

#include "../support/input_error_text.hpp"
#include "boundary_errors.hpp"
#include "lipsync/error.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/closure_refiner.hpp"
#include "lipsync/speech/synthesizer.hpp"
#include "tts_recordings.hpp"

namespace lipsync {
namespace {

using ::testing::HasSubstr;

// Builds WAV bytes of any layout: `value(i, c)` in [-1, 1] for frame i, channel c.
template <typename Value>
std::string make_wav(int rate_hz, int channels, int bits, bool floating, std::size_t frames, Value value) {
  std::string data;
  for (std::size_t i = 0; i < frames; ++i) {
    for (int c = 0; c < channels; ++c) {
      const double v = value(i, c);
      if (floating) {
        const auto f = static_cast<float>(v);
        data.append(reinterpret_cast<const char*>(&f), 4);
        continue;
      }
      if (bits == 8) {
        data.push_back(static_cast<char>(static_cast<std::uint8_t>(std::lround(v * 127) + 128)));
        continue;
      }
      const auto scaled = static_cast<std::int64_t>(std::llround(v * (std::pow(2.0, bits - 1) - 1)));
      for (int b = 0; b < bits / 8; ++b) data.push_back(static_cast<char>((scaled >> (8 * b)) & 0xFF));
    }
  }
  std::string wav = "RIFF";
  const auto u32 = [&](std::uint32_t v) {
    for (int b = 0; b < 4; ++b) wav.push_back(static_cast<char>((v >> (8 * b)) & 0xFF));
  };
  const auto u16 = [&](std::uint16_t v) {
    wav.push_back(static_cast<char>(v & 0xFF));
    wav.push_back(static_cast<char>(v >> 8));
  };
  u32(static_cast<std::uint32_t>(36 + data.size()));
  wav += "WAVEfmt ";
  u32(16);
  u16(floating ? 3 : 1);
  u16(static_cast<std::uint16_t>(channels));
  u32(static_cast<std::uint32_t>(rate_hz));
  u32(static_cast<std::uint32_t>(rate_hz * channels * bits / 8));
  u16(static_cast<std::uint16_t>(channels * bits / 8));
  u16(static_cast<std::uint16_t>(bits));
  wav += "data";
  u32(static_cast<std::uint32_t>(data.size()));
  return wav + data;
}

double tone(std::size_t i, int rate_hz, double hz) {
  return 0.5 * std::sin(2 * std::numbers::pi * hz * double(i) / rate_hz);
}

// Frequency of a tone from its upward zero crossings.
double measured_hz(const speech::PcmAudio& audio) {
  int crossings = 0;
  for (std::size_t i = 1; i < audio.samples.size(); ++i) crossings += audio.samples[i - 1] < 0 && audio.samples[i] >= 0;
  return crossings * double(audio.sample_rate_hz) / double(audio.samples.size());
}

using testing::error_of;

TEST(Synthesis, PhonemesTileTheAudioAndRenderToATrackThatCoversIt) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet espeak = *PhoneSet::builtin("espeak", model);
  for (const char* text : {"Papa parked the car.", "Speech synchronization.", "Where were you, Bob? Mum waved.",
                           "It's easy to tell the depth of a well."}) {
    SCOPED_TRACE(text);
    speech::Synthesis speech = speech::synthesize(text);
    EXPECT_EQ(speech.audio.sample_rate_hz, 22050);
    EXPECT_GT(speech.audio.duration_us(), 500'000);
    const auto& phonemes = speech.phonemes.intervals;
    ASSERT_GE(phonemes.size(), 5U);
    EXPECT_EQ(phonemes.front().start_us, 0);
    EXPECT_EQ(phonemes.back().end_us, speech.audio.duration_us());
    for (std::size_t i = 0; i < phonemes.size(); ++i) {
      EXPECT_LT(phonemes[i].start_us, phonemes[i].end_us) << phonemes[i].label;
      if (i > 0) {
        EXPECT_EQ(phonemes[i].start_us, phonemes[i - 1].end_us) << phonemes[i].label;
      }
      EXPECT_TRUE(espeak.lookup(phonemes[i].label)) << "unknown espeak phoneme '" << phonemes[i].label << "'";
    }
    speech::cover_audio(speech.phonemes, speech.audio.duration_us(), 30);
    const Track track = render_track(model, build_segments(speech.phonemes, model, espeak));
    ASSERT_GT(track.frame_count(), 0U);
    EXPECT_GE(track.t_us.back(), speech.audio.duration_us());
    EXPECT_LE(track.t_us.back(), speech.audio.duration_us() + 1'000'000 / 30 + 1);
  }
}

TEST(Synthesis, BilabialsAreWhereTheTextHasThem) {
  const speech::Synthesis speech = speech::synthesize("Papa parked the car.");
  std::vector<std::string> labels;
  for (const LabeledInterval& phoneme : speech.phonemes.intervals) labels.push_back(phoneme.label);
  EXPECT_EQ(std::count(labels.begin(), labels.end(), "p"), 3);
}

TEST(Synthesis, EachWordOfTheTextStartsAtItsFirstPhoneme) {
  // From espeak-ng's word events: one start per word of the text as white space separates them (a
  // number read as several words is one), each where that word's first phoneme starts.
  const auto first_labels = [](const speech::Synthesis& speech) {
    std::vector<std::string> labels;
    for (const std::int64_t start_us : speech.word_starts_us) {
      const auto phoneme = std::find_if(speech.phonemes.intervals.begin(), speech.phonemes.intervals.end(),
                                        [&](const LabeledInterval& p) { return p.start_us == start_us; });
      labels.push_back(phoneme == speech.phonemes.intervals.end() ? "(none)" : phoneme->label);
    }
    return labels;
  };
  EXPECT_THAT(first_labels(speech::synthesize("Papa parked the car.")), ::testing::ElementsAre("p", "p", "D", "k"));
  const speech::Synthesis numbers = speech::synthesize("Bob ate 123 plums.");
  EXPECT_THAT(first_labels(numbers), ::testing::ElementsAre("b", "eI", "w", "p"));
  EXPECT_TRUE(std::is_sorted(numbers.word_starts_us.begin(), numbers.word_starts_us.end()));
  EXPECT_THAT(first_labels(speech::synthesize("Il bambino, beve il latte.", {.voice = "it"})),
              ::testing::ElementsAre("i", "b", "b", "i", "l"));
}

TEST(Synthesis, TheSameTextGivesTheSameSpeechWhateverTheProcessSpokeBefore) {
  // espeak-ng's wave generator carries state from one utterance to the next; each
  // synthesis runs in a fresh child process, so a long-running caller (lipsyncd) gets
  // what `lipsync say` gets.
  const speech::Synthesis first = speech::synthesize("Papa parked the car.");
  speech::synthesize("Where were you, Bob? Mum waved from the ferry.");
  const speech::Synthesis again = speech::synthesize("Papa parked the car.");
  EXPECT_TRUE(again.audio.samples == first.audio.samples) << "the audio differs";
  ASSERT_EQ(again.phonemes.intervals.size(), first.phonemes.intervals.size());
  for (std::size_t i = 0; i < first.phonemes.intervals.size(); ++i) {
    EXPECT_EQ(again.phonemes.intervals[i].start_us, first.phonemes.intervals[i].start_us) << i;
    EXPECT_EQ(again.phonemes.intervals[i].end_us, first.phonemes.intervals[i].end_us) << i;
    EXPECT_EQ(again.phonemes.intervals[i].label, first.phonemes.intervals[i].label) << i;
  }
}

TEST(Synthesis, UnknownVoiceAndEmptyTextAreErrors) {
  speech::SynthesisOptions options;
  options.voice = "no-such-voice";
  EXPECT_THAT(error_of([&] { speech::synthesize("Hello.", options); }), HasSubstr("unknown voice 'no-such-voice'"));
  EXPECT_THAT(error_of([] { speech::synthesize("  \n"); }), HasSubstr("the text is empty"));
  // The failed calls leave espeak-ng usable.
  EXPECT_FALSE(speech::synthesize("Hello.").phonemes.intervals.empty());
}

TEST(Wav, WrittenAudioReadsBackUnchanged) {
  speech::PcmAudio audio;
  audio.sample_rate_hz = 16000;
  for (int i = 0; i < 1000; ++i) audio.samples.push_back(static_cast<std::int16_t>(i * 37 - 18000));
  std::ostringstream out;
  speech::write_wav(out, audio);
  const speech::DecodedWav decoded = speech::decode_wav(out.str(), "x.wav");
  EXPECT_EQ(decoded.audio.samples, audio.samples);
  EXPECT_EQ(decoded.audio.sample_rate_hz, 16000);
  EXPECT_TRUE(decoded.notes.empty());
}

TEST(Wav, OtherLayoutsAreConvertedToMono16BitWithANote) {
  struct Layout {
    int rate, channels, bits;
    bool floating;
    std::vector<std::string> notes;
  };
  const Layout layouts[] = {
      {44100, 2, 24, false, {"2 channels averaged to mono", "24-bit integer samples converted to 16-bit"}},
      {48000, 1, 32, true, {"32-bit float samples converted to 16-bit"}},
      {8000, 1, 8, false, {"8-bit integer samples converted to 16-bit"}},
      {22050, 2, 32, false, {"2 channels averaged to mono", "32-bit integer samples converted to 16-bit"}},
  };
  for (const Layout& layout : layouts) {
    SCOPED_TRACE(std::to_string(layout.rate) + " Hz, " + std::to_string(layout.bits) + " bits");
    // 440 Hz in the left channel, its copy in the right: the mono mix is the same tone.
    const std::string wav =
        make_wav(layout.rate, layout.channels, layout.bits, layout.floating, std::size_t(layout.rate),
                 [&](std::size_t i, int) { return tone(i, layout.rate, 440); });
    const speech::DecodedWav decoded = speech::decode_wav(wav, "x.wav");
    EXPECT_EQ(decoded.notes, layout.notes);
    EXPECT_EQ(decoded.audio.samples.size(), std::size_t(layout.rate));
    const speech::PcmAudio at_16k = speech::resample(decoded.audio, 16000);
    EXPECT_EQ(at_16k.samples.size(), 16000U);
    EXPECT_NEAR(measured_hz(at_16k), 440, 2);
    const auto peak = *std::max_element(at_16k.samples.begin(), at_16k.samples.end());
    EXPECT_NEAR(peak, 16384, 16384 * 0.03);  // amplitude 0.5 kept (8-bit: within its precision)
  }
}

TEST(Wav, ResamplingRemovesWhat16KhzCannotHold) {
  // A 7 kHz tone passes; a 10 kHz tone (above 8 kHz Nyquist) would alias to 6 kHz: it must vanish.
  for (const auto& [hz, kept] : {std::pair{7000.0, true}, std::pair{10000.0, false}}) {
    // clang 14 (the ASan build) cannot capture a structured binding in a lambda: capture a copy.
    const std::string wav =
        make_wav(44100, 1, 16, false, 44100, [hz = hz](std::size_t i, int) { return tone(i, 44100, hz); });
    const speech::PcmAudio out = speech::resample(speech::decode_wav(wav, "x.wav").audio, 16000);
    const auto peak = *std::max_element(out.samples.begin() + 1000, out.samples.end() - 1000);
    if (kept) {
      EXPECT_GT(peak, 14000) << hz;
    } else {
      EXPECT_LT(peak, 200) << hz;
    }
  }
}

TEST(Wav, BadFilesAreRefusedNamingTheFileAndWhatWasFound) {
  EXPECT_EQ(error_of([] { speech::decode_wav("ID3\x03 an mp3 file", "song.mp3"); }),
            "song.mp3: not a WAV file (expected a RIFF/WAVE header, found 'ID3\x03')");
  EXPECT_EQ(error_of([] { speech::decode_wav("RIFF", "short.wav"); }),
            "short.wav: not a WAV file (expected a RIFF/WAVE header, found 4 bytes)");
  std::string adpcm = make_wav(16000, 1, 16, false, 100, [](std::size_t, int) { return 0.0; });
  adpcm[20] = 2;  // format tag 2: Microsoft ADPCM
  EXPECT_EQ(error_of([&] { speech::decode_wav(adpcm, "a.wav"); }),
            "a.wav: unsupported WAV encoding (format tag 2, 16 bits): only PCM 8/16/24/32-bit integer and "
            "32/64-bit float are read");
  const std::string no_data = make_wav(16000, 1, 16, false, 0, [](std::size_t, int) { return 0.0; }).substr(0, 36);
  EXPECT_EQ(error_of([&] { speech::decode_wav(no_data, "n.wav"); }), "n.wav: WAV file has no 'data' chunk");
}

// Every word of `aligned` starts where a spoken phone starts and ends where one ends, also
// where the closure refiner moved its lip boundaries (or gave a pause before a /p b/ to the
// stop).
void expect_words_start_and_end_with_their_phones(const speech::Alignment& aligned, const std::string& what) {
  const std::vector<LabeledInterval>& phones = aligned.phones.intervals;
  for (const LabeledInterval& word : aligned.words) {
    const auto first = std::find_if(phones.begin(), phones.end(),
                                    [&](const LabeledInterval& p) { return p.start_us == word.start_us; });
    const auto last =
        std::find_if(phones.begin(), phones.end(), [&](const LabeledInterval& p) { return p.end_us == word.end_us; });
    ASSERT_NE(first, phones.end()) << what << ": '" << word.label << "' starts inside a phone, at " << word.start_us;
    ASSERT_NE(last, phones.end()) << what << ": '" << word.label << "' ends inside a phone, at " << word.end_us;
    EXPECT_FALSE(first->label.empty()) << what << ": '" << word.label << "' starts with a pause";
    EXPECT_FALSE(last->label.empty()) << what << ": '" << word.label << "' ends with a pause";
  }
}

TEST(Alignment, SyntheticSpeechAlignsWithinTheReportedError) {
  // The figures of docs/input-formats.md, "Speech in": espeak-ng speech of the ten
  // sentences, force-aligned, against espeak-ng's own phoneme boundaries, its stops
  // moved back from their bursts to their closures' silence (the acoustic closure,
  // tts_recordings.hpp). Each synthesis runs in a fresh espeak-ng, so the figures are
  // reproducible; the bounds are the reported figures (refined, the default) rounded
  // outward: 15 of 15 bilabial closures within 20 ms, median 7.4 ms, p95 9.4 ms (13 of
  // 15 and a p95 of 180 ms before a pause over loud formants was refused and an /m/'s
  // murmur moved its closure; 7 of 15 before the refiner took a pause before /p b/ for
  // its closure).
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet espeak = *PhoneSet::builtin("espeak", model);
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  testing::BoundaryScore score;
  for (const char* sentence : testing::accuracy_sentences()) {
    speech::Synthesis speech = speech::synthesize(sentence);
    testing::espeak_stops_from_their_closures(speech.audio, speech.phonemes);
    speech::AlignmentOptions options;
    options.transcript = sentence;
    const speech::Alignment aligned = speech::align_speech(speech.audio, "espeak-ng", options);
    ASSERT_EQ(aligned.words.size(), speech::transcript_words(sentence).size()) << sentence;
    expect_words_start_and_end_with_their_phones(aligned, sentence);
    testing::score_alignment(speech.phonemes, espeak, aligned.phones, arpabet, model, score);
  }
  EXPECT_LE(testing::quantile(score.errors_ms, 0.5), 10.0);
  EXPECT_LE(testing::quantile(score.errors_ms, 0.95), 60.0);
  EXPECT_GE(double(score.matched_phonemes) / score.reference_phonemes, 0.85);
  EXPECT_EQ(score.bilabials, 15);
  EXPECT_EQ(score.bilabials_within_20ms, 15) << "of " << score.bilabials;
  EXPECT_LE(testing::quantile(score.bilabial_errors_ms, 0.5), 8.0);
  EXPECT_LE(testing::quantile(score.bilabial_errors_ms, 0.95), 12.0);
  EXPECT_GE(score.bilabials_closed_at_middle, 14);
  EXPECT_EQ(score.false_closures, 0);
}

TEST(Alignment, RefinedBilabialClosuresOfFliteAndFestivalSpeechStartWithin20Ms) {
  // docs/input-formats.md, "Closures refined from the signal": the ten sentences spoken by
  // flite (slt) and Festival (kal_diphone), force-aligned, scored as the recogniser left
  // them and after refine_closures (the same decode). Refined: 15/15 on both (raw 13/15
  // and 9/15) bilabials within 20 ms, the issue's goal of 95 %; their start errors'
  // median 7.8 ms and p95 17.2 ms at worst; the bounds below are those figures rounded
  // outward.
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet radio = *PhoneSet::builtin("radio", model);
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  const std::filesystem::path wav =
      std::filesystem::temp_directory_path() / ("speech_test-" + std::to_string(::getpid()) + ".wav");
  for (const bool festival : {false, true}) {
    testing::BoundaryScore raw, refined;
    for (const char* sentence : testing::accuracy_sentences()) {
      const auto recording =
          festival ? testing::festival_recording(sentence, wav) : testing::flite_recording(sentence, wav);
      ASSERT_TRUE(recording) << (festival ? "festival" : "flite") << " did not speak: " << sentence;
      speech::AlignmentOptions options;
      options.transcript = sentence;
      options.refine_closures = false;
      speech::Alignment aligned = speech::align_speech(recording->audio, "tts.wav", options);
      testing::score_alignment(recording->phonemes, radio, aligned.phones, arpabet, model, raw);
      speech::refine_closures(speech::resample(recording->audio, 16000), aligned.phones);
      testing::score_alignment(recording->phonemes, radio, aligned.phones, arpabet, model, refined);
    }
    const char* name = festival ? "Festival" : "flite";
    EXPECT_EQ(refined.bilabials, 15) << name;
    EXPECT_EQ(refined.bilabials_within_20ms, 15) << name << " (raw: " << raw.bilabials_within_20ms << ")";
    EXPECT_GT(refined.bilabials_within_20ms, raw.bilabials_within_20ms) << name;
    EXPECT_LE(testing::quantile(refined.bilabial_errors_ms, 0.5), 9.0) << name;
    EXPECT_LE(testing::quantile(refined.bilabial_errors_ms, 0.95), 20.0) << name;
    EXPECT_EQ(refined.bilabials_closed_at_middle, 15) << name;
  }
  std::filesystem::remove(wav);
}

TEST(Alignment, WithoutATranscriptBilabialsShowClosedAtLeastAsOftenAsMeasured) {
  // docs/input-formats.md, "Without a transcript": the ten sentences spoken by espeak-ng,
  // flite and Festival, aligned from the audio alone (the words heard, or the phone loop's
  // phones where those do not fit) and refined (the default), scored at the middle of
  // every reference /p b m/ ("closed at middle") and of every other phoneme ("false
  // closures": a /p b m/ shown where the lips should be open). Measured: closed 10, 13 and
  // 14 of 15; false closures 8/230, 2/240 and 1/240. A change to the recogniser or the
  // refiner must not lose a closure or add a false one.
  struct Voice {
    const char* name;
    int closed;
    int false_closures;
  };
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  const std::filesystem::path wav =
      std::filesystem::temp_directory_path() / ("speech_test-free-" + std::to_string(::getpid()) + ".wav");
  for (const Voice voice : {Voice{"espeak-ng", 10, 8}, Voice{"flite", 13, 2}, Voice{"festival", 14, 1}}) {
    const std::string name = voice.name;
    const PhoneSet reference_set = *PhoneSet::builtin(name == "espeak-ng" ? "espeak" : "radio", model);
    testing::BoundaryScore score;
    for (const char* sentence : testing::accuracy_sentences()) {
      std::optional<testing::Recording> recording;
      if (name == "espeak-ng") {
        speech::Synthesis speech = speech::synthesize(sentence);
        testing::espeak_stops_from_their_closures(speech.audio, speech.phonemes);
        recording = testing::Recording{std::move(speech.audio), std::move(speech.phonemes)};
      } else {
        recording =
            name == "flite" ? testing::flite_recording(sentence, wav) : testing::festival_recording(sentence, wav);
      }
      ASSERT_TRUE(recording) << name << " did not speak: " << sentence;
      const speech::Alignment aligned = speech::align_speech(recording->audio, name, {});
      testing::score_alignment(recording->phonemes, reference_set, aligned.phones, arpabet, model, score);
    }
    EXPECT_EQ(score.bilabials, 15) << name;
    EXPECT_GE(score.bilabials_closed_at_middle, voice.closed) << name;
    EXPECT_LE(score.false_closures, voice.false_closures) << name << " of " << score.other_phonemes;
  }
  std::filesystem::remove(wav);
}

TEST(Alignment, WithoutATranscriptTheWordsHeardAreAlignedWhereTheyFitAndThePhoneLoopServesWhereNot) {
  const std::filesystem::path wav =
      std::filesystem::temp_directory_path() / ("speech_test-heard-" + std::to_string(::getpid()) + ".wav");
  // flite's "Rice is often served in round bowls", heard as "prices offensive in round
  // bills": the /b/ of its last word comes from the word heard, where the phone loop hears /d/.
  const std::optional<testing::Recording> flite = testing::flite_recording(testing::accuracy_sentences()[4], wav);
  std::filesystem::remove(wav);
  ASSERT_TRUE(flite);
  const speech::Alignment heard = speech::align_speech(flite->audio, "rice.wav", {});
  ASSERT_FALSE(heard.words.empty());
  EXPECT_TRUE(std::any_of(heard.words.begin(), heard.words.end(),
                          [](const LabeledInterval& word) { return word.label == "round"; }));
  const LabeledInterval& last_word = heard.words.back();
  EXPECT_TRUE(std::any_of(heard.phones.intervals.begin(), heard.phones.intervals.end(),
                          [&](const LabeledInterval& phone) {
                            return phone.label == "B" && phone.start_us >= last_word.start_us &&
                                   phone.end_us <= last_word.end_us;
                          }))
      << "no /b/ in the last word heard, '" << last_word.label << "'";
  ASSERT_FALSE(heard.notes.empty());
  EXPECT_NE(heard.notes.back().find("no transcript: aligned to the words recognised (\""), std::string::npos)
      << heard.notes.back();
  // espeak-ng's formant voice is heard as a few wrong words that leave its speech in
  // pauses, in the recording as it is and over a noise floor ("american nuclear bomb us
  // who planned"): the phones come from the phone loop, with no words and no such note.
  const speech::Synthesis espeak = speech::synthesize(testing::accuracy_sentences()[0]);
  const speech::Alignment looped = speech::align_speech(espeak.audio, "birch.wav", {});
  EXPECT_TRUE(looped.words.empty());
  EXPECT_GT(looped.phones.intervals.size(), 20U);
  for (const std::string& note : looped.notes) EXPECT_EQ(note.find("words recognised"), std::string::npos) << note;
  // Its "The box was thrown beside the parked truck" is heard as "the box was through that"
  // (which does not fit), and over the noise floor as "the box with road beside the parked
  // truck" (which does): the /p/ of "parked" comes from that word.
  const speech::Synthesis box = speech::synthesize(testing::accuracy_sentences()[6]);
  const speech::Alignment over_noise = speech::align_speech(box.audio, "box.wav", {});
  const auto parked = std::find_if(over_noise.words.begin(), over_noise.words.end(),
                                   [](const LabeledInterval& word) { return word.label == "parked"; });
  ASSERT_NE(parked, over_noise.words.end()) << "'parked' not heard";
  // The refiner gives the pause before "parked" to its /p/: the word starts with that closure.
  EXPECT_TRUE(std::any_of(
      over_noise.phones.intervals.begin(), over_noise.phones.intervals.end(), [&](const LabeledInterval& phone) {
        return phone.label == "P" && phone.start_us == parked->start_us && phone.end_us <= parked->end_us;
      }));
  expect_words_start_and_end_with_their_phones(over_noise, "box.wav");
  ASSERT_FALSE(over_noise.notes.empty());
  EXPECT_NE(over_noise.notes.back().find("words recognised"), std::string::npos) << over_noise.notes.back();
}

TEST(Alignment, WordsAndPhonesFollowTheTranscript) {
  const speech::Synthesis speech = speech::synthesize("Papa parked the car.");
  speech::AlignmentOptions options;
  options.transcript = "Papa parked the car.";
  const speech::Alignment aligned = speech::align_speech(speech.audio, "papa.wav", options);
  std::vector<std::string> words, phones;
  for (const LabeledInterval& word : aligned.words) words.push_back(word.label);
  for (const LabeledInterval& phone : aligned.phones.intervals)
    if (!phone.label.empty()) phones.push_back(phone.label);
  EXPECT_THAT(words, ::testing::ElementsAre("papa", "parked", "the", "car"));
  EXPECT_THAT(phones,
              ::testing::ElementsAre("P", "AA", "P", "AH", "P", "AA", "R", "K", "T", "DH", "AH", "K", "AA", "R"));
  EXPECT_EQ(aligned.notes, std::vector<std::string>{"resampled from 22050 Hz to 16000 Hz"});
  EXPECT_EQ(aligned.phones.intervals.front().start_us, 0);
  EXPECT_EQ(aligned.phones.intervals.back().end_us, speech::resample(speech.audio, 16000).duration_us());
}

TEST(Alignment, WithoutATranscriptPhonesAreRecognised) {
  const speech::Synthesis speech = speech::synthesize("Papa parked the car.");
  // Heard over the noise floor as "political or to the dollar", which fits: the phones
  // come from those words (the phone loop's where no words fit); either way they are phones.
  const speech::Alignment recognised = speech::align_speech(speech.audio, "papa.wav", {});
  const auto spoken = std::count_if(recognised.phones.intervals.begin(), recognised.phones.intervals.end(),
                                    [](const LabeledInterval& phone) { return !phone.label.empty(); });
  EXPECT_GE(spoken, 5);
}

TEST(Alignment, SilenceOnlyIsAnError) {
  speech::PcmAudio silence;
  silence.samples.assign(32000, 0);
  EXPECT_EQ(error_of([&] { speech::align_speech(silence, "quiet.wav", {}); }),
            "quiet.wav: no speech found: the audio is silent (its loudest 20 ms is at -200 dBFS)");
  for (std::size_t i = 0; i < silence.samples.size(); ++i)
    silence.samples[i] = static_cast<std::int16_t>(i % 3 == 0 ? 20 : -10);
  EXPECT_THAT(error_of([&] { speech::align_speech(silence, "hiss.wav", {}); }), HasSubstr("no speech found"));
}

TEST(Alignment, TenMinutesOfAudioAreRefusedAtOnce) {
  speech::PcmAudio long_audio;
  long_audio.samples.resize(std::size_t(600) * 16000);
  for (std::size_t i = 0; i < long_audio.samples.size(); ++i)
    long_audio.samples[i] = static_cast<std::int16_t>(tone(i, 16000, 200) * 20000);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(error_of([&] { speech::align_speech(long_audio, "long.wav", {}); }),
            "long.wav: 600.0 s of audio is longer than the 120 s an alignment accepts; split it at pauses");
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
}

TEST(Alignment, ATranscriptThatDoesNotFitIsAnError) {
  const speech::Synthesis speech = speech::synthesize("Papa parked the car.");
  speech::AlignmentOptions options;
  options.transcript = "The quick brown fox jumps over the lazy dog near the river bank today and tomorrow";
  EXPECT_EQ(error_of([&] { speech::align_speech(speech.audio, "papa.wav", options); }),
            "papa.wav: the transcript does not match the audio (no alignment of its 16 words fits)");
  options.transcript = "Hello";
  EXPECT_THAT(error_of([&] { speech::align_speech(speech.audio, "papa.wav", options); }),
              HasSubstr("papa.wav: the transcript does not match the audio (its 1 word fit only by leaving"));
}

TEST(Alignment, AWordMissingFromTheDictionaryIsNamed) {
  const speech::Synthesis speech = speech::synthesize("Papa parked the car.");
  speech::AlignmentOptions options;
  options.transcript = "Papa parked the xyzzyq.";
  EXPECT_EQ(error_of([&] { speech::align_speech(speech.audio, "papa.wav", options); }),
            "papa.wav: transcript word 4 'xyzzyq' is not in the pronouncing dictionary (write numbers and "
            "abbreviations out as words)");
}

TEST(Alignment, TranscriptWordsDropPunctuationAndQuotes) {
  EXPECT_THAT(speech::transcript_words("\"It's 'easy', Bob!\" --well..."),
              ::testing::ElementsAre("it's", "easy", "bob", "well"));
}

TEST(Alignment, TheTextgridReadsBackAsTheAlignment) {
  const speech::Synthesis speech = speech::synthesize("Papa parked the car.");
  speech::AlignmentOptions options;
  options.transcript = "Papa parked the car.";
  const speech::Alignment aligned = speech::align_speech(speech.audio, "papa.wav", options);
  std::ostringstream grid;
  speech::write_textgrid(grid, aligned, aligned.phones.intervals.back().end_us);
  const LabeledUtterance phones = parse_utterance(grid.str(), InputFormat::textgrid, "papa.TextGrid");
  ASSERT_EQ(phones.intervals.size(), aligned.phones.intervals.size());
  for (std::size_t i = 0; i < phones.intervals.size(); ++i) {
    EXPECT_EQ(phones.intervals[i].label, aligned.phones.intervals[i].label);
    EXPECT_EQ(phones.intervals[i].start_us, aligned.phones.intervals[i].start_us);
    EXPECT_EQ(phones.intervals[i].end_us, aligned.phones.intervals[i].end_us);
  }
  ParseOptions words_tier;
  words_tier.tier = "words";
  const LabeledUtterance words = parse_utterance(grid.str(), InputFormat::textgrid, "papa.TextGrid", words_tier);
  std::vector<std::string> labels;
  for (const LabeledInterval& word : words.intervals)
    if (!word.label.empty()) labels.push_back(word.label);
  EXPECT_THAT(labels, ::testing::ElementsAre("papa", "parked", "the", "car"));
}

}  // namespace
}  // namespace lipsync
