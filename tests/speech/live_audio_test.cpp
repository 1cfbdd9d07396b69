// Live audio in, below the server: the streaming resampler equals the whole-buffer one, the
// stream reader equals decode_wav however the bytes are split and names what is wrong, and the
// live recogniser, fed real TTS speech (flite, Festival) in 20 ms pieces, gives final phones that
// tile the audio, cuts utterances at pauses and skips the silence between them, and labels the
// synthesisers' own /p b m/ at their middles as the offline aligner does.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "../support/harvard_sentences.hpp"
#include "boundary_errors.hpp"
#include "lipsync/error.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/live_recognizer.hpp"
#include "tts_recordings.hpp"

namespace lipsync::speech {
namespace {

std::vector<std::int16_t> noise_like_speech(std::size_t n, std::uint32_t seed) {
  std::mt19937 random(seed);
  std::normal_distribution<double> gauss(0, 3000);
  std::vector<std::int16_t> samples(n);
  double low = 0;
  for (std::int16_t& s : samples) {
    low = 0.9 * low + 0.1 * gauss(random);  // some low-pass, so that the resampler's band matters
    s = static_cast<std::int16_t>(std::clamp(low * 3, -32768.0, 32767.0));
  }
  return samples;
}

TEST(StreamingResampler, GivesResampleOfTheWholeInputHoweverItIsCut) {
  for (const int rate : {8000, 11025, 22050, 44100, 48000, 16000}) {
    SCOPED_TRACE(rate);
    PcmAudio whole;
    whole.sample_rate_hz = rate;
    whole.samples = noise_like_speech(static_cast<std::size_t>(rate) / 3 + 17, static_cast<std::uint32_t>(rate));
    const PcmAudio expected = resample(whole, 16000);
    std::mt19937 random(7);
    std::vector<std::int16_t> streamed;
    StreamingResampler resampler(rate, 16000);
    for (std::size_t at = 0; at < whole.samples.size();) {
      const std::size_t n = std::min<std::size_t>(whole.samples.size() - at, 1 + random() % 700);
      resampler.push(std::span(whole.samples).subspan(at, n), streamed);
      at += n;
    }
    resampler.finish(streamed);
    EXPECT_EQ(streamed, expected.samples);
  }
}

/// A WAV file's bytes, written by hand: `channels` interleaved 16-bit channels, the data size as
/// `declared` (a streaming writer's 0xFFFFFFFF, or the real one), a LIST chunk before the data.
std::string stereo_wav(const std::vector<std::int16_t>& left, const std::vector<std::int16_t>& right,
                       std::uint32_t declared) {
  std::string b;
  const auto u32 = [&](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) b.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
  };
  const auto u16 = [&](std::uint16_t v) {
    b.push_back(static_cast<char>(v & 0xFF));
    b.push_back(static_cast<char>(v >> 8));
  };
  b += "RIFF";
  u32(0xFFFFFFFF);
  b += "WAVEfmt ";
  u32(16);
  u16(1);
  u16(2);
  u32(22050);
  u32(22050 * 4);
  u16(4);
  u16(16);
  b += "LIST";
  u32(5);
  b += "odd!!";
  b.push_back('\0');  // the pad byte of an odd-sized chunk
  b += "data";
  u32(declared);
  for (std::size_t i = 0; i < left.size(); ++i) {
    u16(static_cast<std::uint16_t>(left[i]));
    u16(static_cast<std::uint16_t>(right[i]));
  }
  return b;
}

TEST(AudioStreamReader, ReadsAWavSplitAnywhereAsDecodeWavReadsItWhole) {
  const std::vector<std::int16_t> left = noise_like_speech(3001, 1), right = noise_like_speech(3001, 2);
  for (const std::uint32_t declared : {0xFFFFFFFFU, 3001U * 4}) {
    std::string wav = stereo_wav(left, right, declared);
    const DecodedWav expected = decode_wav(wav, "x.wav");
    if (declared != 0xFFFFFFFFU) wav += "JUNKtrailing chunk";  // bytes after the declared data are not samples
    std::mt19937 random(declared);
    AudioStreamReader reader(AudioStreamReader::Encoding::wav, 0, 0, "audio");
    std::vector<std::int16_t> samples;
    for (std::size_t at = 0; at < wav.size();) {
      const std::size_t n = std::min<std::size_t>(wav.size() - at, 1 + random() % 9);
      reader.push(std::string_view(wav).substr(at, n), samples);
      at += n;
    }
    EXPECT_NO_THROW(reader.finish());
    EXPECT_EQ(reader.sample_rate_hz(), 22050);
    EXPECT_EQ(reader.layout().channels, 2);
    EXPECT_EQ(samples, expected.audio.samples);
  }
}

TEST(AudioStreamReader, RawStereoPcmIsMixedDownAcrossPiecesThatSplitASample) {
  const std::vector<std::int16_t> left = noise_like_speech(500, 3), right = noise_like_speech(500, 4);
  const std::string wav = stereo_wav(left, right, 2000);
  const std::string pcm = wav.substr(wav.size() - 2000);
  AudioStreamReader reader(AudioStreamReader::Encoding::pcm_s16le, 22050, 2, "audio");
  std::vector<std::int16_t> samples;
  for (std::size_t at = 0; at < pcm.size(); at += 3) reader.push(std::string_view(pcm).substr(at, 3), samples);
  reader.finish();
  EXPECT_EQ(samples, decode_wav(wav, "x.wav").audio.samples);
}

std::string error_of(const std::function<void()>& action) {
  try {
    action();
  } catch (const InputError& error) {
    return error.what();
  }
  return "no error";
}

TEST(AudioStreamReader, NamesWhatIsWrongWithTheStream) {
  std::vector<std::int16_t> out;
  EXPECT_EQ(error_of([&] {
              AudioStreamReader reader(AudioStreamReader::Encoding::wav, 0, 0, "audio");
              reader.push(std::string("OggS\0\0\0\0\0\0\0\0\0\0\0\0", 16), out);
            }),
            "audio: not a WAV file (expected a RIFF/WAVE header, found 'OggS')");
  const std::string wav = stereo_wav({1, 2}, {3, 4}, 8);
  EXPECT_EQ(error_of([&] {
              AudioStreamReader reader(AudioStreamReader::Encoding::wav, 16000, 0, "audio");
              reader.push(wav, out);
            }),
            "audio: the WAV header says 22050 Hz, but the stream's sample_rate_hz is 16000");
  EXPECT_EQ(error_of([&] {
              AudioStreamReader reader(AudioStreamReader::Encoding::wav, 0, 0, "audio");
              reader.push(wav.substr(0, 30), out);
              reader.finish();
            }),
            "audio: the stream ended inside the WAV header (30 bytes, no 'data' chunk)");
  EXPECT_EQ(error_of([&] {
              AudioStreamReader reader(AudioStreamReader::Encoding::pcm_s16le, 16000, 2, "audio");
              reader.push("abcde", out);
              reader.finish();
            }),
            "audio: the stream ended inside a sample frame (1 bytes left over; a frame is 4 bytes)");
  std::string endless_header = wav.substr(0, 36) + "LIST";
  endless_header += std::string("\xff\xff\x00\x00", 4) + std::string(70'000, 'x');
  EXPECT_NE(error_of([&] {
              AudioStreamReader reader(AudioStreamReader::Encoding::wav, 0, 0, "audio");
              reader.push(endless_header, out);
            }).find("longer than 65536 bytes without its 'data' chunk"),
            std::string::npos);
}

/// Feeds `audio` to `recognizer` in 20 ms pieces, calling `before_piece` with each piece's end
/// (µs) before it; returns every final phone, in order.
std::vector<LabeledInterval> recognise_in_pieces(
    const PcmAudio& audio, LiveRecognizer& recognizer,
    const std::function<void(std::int64_t)>& before_piece = [](std::int64_t) {}) {
  std::vector<LabeledInterval> phones;
  const std::size_t piece = static_cast<std::size_t>(audio.sample_rate_hz) / 50;
  for (std::size_t at = 0; at < audio.samples.size(); at += piece) {
    before_piece(static_cast<std::int64_t>(std::min(at + piece, audio.samples.size())) * 1'000'000 /
                 audio.sample_rate_hz);
    recognizer.push(std::span(audio.samples).subspan(at, std::min(piece, audio.samples.size() - at)));
    for (LabeledInterval& phone : recognizer.take_final()) phones.push_back(std::move(phone));
    const std::vector<LabeledInterval> guess = recognizer.guess();
    // The guess always continues the phones taken, up to what was heard.
    if (!guess.empty()) {
      EXPECT_EQ(guess.front().start_us, recognizer.taken_us());
      EXPECT_EQ(guess.back().end_us, recognizer.heard_us());
    }
  }
  recognizer.finish();
  for (LabeledInterval& phone : recognizer.take_final()) phones.push_back(std::move(phone));
  return phones;
}

void expect_tiles(const std::vector<LabeledInterval>& phones, std::int64_t end_us) {
  ASSERT_FALSE(phones.empty());
  EXPECT_EQ(phones.front().start_us, 0);
  for (std::size_t i = 1; i < phones.size(); ++i) {
    EXPECT_EQ(phones[i].start_us, phones[i - 1].end_us) << "phone " << i;
    EXPECT_LT(phones[i].start_us, phones[i].end_us) << "phone " << i;
    EXPECT_FALSE(phones[i].label.empty() && phones[i - 1].label.empty()) << "two silences in a row at " << i;
  }
  EXPECT_EQ(phones.back().end_us, end_us);
}

TEST(LiveRecognizer, FinalPhonesTileTheAudioAndShowFlitesAndFestivalsClosuresAtTheirMiddles) {
  // Sentences 11-20 of the Harvard lists, spoken by flite and Festival and heard in 20 ms
  // pieces with the transcript: every final phone follows the last, the whole audio is
  // covered, and the synthesisers' own /p b m/ are labelled /p b m/ at their middles.
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet radio = *PhoneSet::builtin("radio", model);
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  const auto wav = std::filesystem::temp_directory_path() / ("live_audio_test-" + std::to_string(::getpid()) + ".wav");
  for (const bool festival : {false, true}) {
    testing::BoundaryScore score;
    for (std::size_t s = 10; s < 20; ++s) {
      const char* sentence = testing::kHarvardSentences[s];
      const auto recording =
          festival ? testing::festival_recording(sentence, wav) : testing::flite_recording(sentence, wav);
      ASSERT_TRUE(recording) << sentence;
      LiveRecognitionOptions options;
      options.transcript = sentence;
      options.sample_rate_hz = recording->audio.sample_rate_hz;
      LiveRecognizer recognizer(options, "live");
      LabeledUtterance heard;
      heard.phone_set = "arpabet";
      heard.intervals = recognise_in_pieces(recording->audio, recognizer);
      SCOPED_TRACE(sentence);
      expect_tiles(heard.intervals, recording->audio.duration_us());
      testing::score_alignment(recording->phonemes, radio, heard, arpabet, model, score);
    }
    // Measured: see docs/streaming.md, "Live audio".
    EXPECT_GE(score.bilabials_closed_at_middle * 10, score.bilabials * 9) << (festival ? "festival" : "flite");
  }
  std::filesystem::remove(wav);
}

TEST(LiveRecognizer, CutsUtterancesAtPausesTakesTheSilenceBetweenThemAsOneAndHearsEachAsTheFirst) {
  const auto wav =
      std::filesystem::temp_directory_path() / ("live_audio_test-cut-" + std::to_string(::getpid()) + ".wav");
  const auto recording = testing::flite_recording("Papa bought five more big maps.", wav);
  std::filesystem::remove(wav);
  ASSERT_TRUE(recording);
  PcmAudio audio = recording->audio;
  const std::size_t speech = audio.samples.size();
  audio.samples.insert(audio.samples.end(), static_cast<std::size_t>(audio.sample_rate_hz) * 3, 0);
  audio.samples.insert(audio.samples.end(), recording->audio.samples.begin(), recording->audio.samples.end());
  audio.samples.insert(audio.samples.end(), static_cast<std::size_t>(audio.sample_rate_hz), 0);  // a pause ends it too
  LiveRecognitionOptions options;
  options.sample_rate_hz = audio.sample_rate_hz;
  LiveRecognizer recognizer(options, "live");
  const std::vector<LabeledInterval> phones = recognise_in_pieces(audio, recognizer);
  expect_tiles(phones, audio.duration_us());
  EXPECT_EQ(recognizer.utterances(), 2U);
  // One silence holds the three seconds between the two sentences.
  const std::int64_t gap_middle_us = (static_cast<std::int64_t>(speech) * 1'000'000 / audio.sample_rate_hz) + 1'500'000;
  const auto holding = std::find_if(phones.begin(), phones.end(), [&](const LabeledInterval& phone) {
    return phone.start_us <= gap_middle_us && gap_middle_us < phone.end_us;
  });
  ASSERT_NE(holding, phones.end());
  EXPECT_TRUE(holding->label.empty());
  EXPECT_GE(holding->end_us - holding->start_us, 2'800'000);
  // The second sentence is heard as the first was: each utterance starts from the model's own
  // state (its frames counted from its start, the cepstral means the model begins with), however
  // much audio came before it.
  std::vector<LabeledInterval> first(phones.begin(), holding), second(holding + 1, phones.end());
  const std::int64_t offset_us = holding->end_us;
  ASSERT_FALSE(first.empty());
  while (!first.empty() && first.front().label.empty()) first.erase(first.begin());
  while (!first.empty() && first.back().label.empty()) first.pop_back();
  while (!second.empty() && second.back().label.empty()) second.pop_back();
  ASSERT_EQ(first.size(), second.size());
  for (std::size_t i = 0; i < first.size(); ++i) {
    EXPECT_EQ(second[i].label, first[i].label) << "phone " << i;
  }
  EXPECT_GT(offset_us, 0);
}

TEST(LiveRecognizer, ADecoderLoadedAheadHearsExactlyWhatOneLoadedByTheRecognizerHears) {
  // Flite's sentence, then a pause and the sentence again: with the transcript given once, the
  // second runs past the transcript's last word onto the phone loop; without one, all of it is on
  // the phone loop. A decoder prepared ahead (on another thread, as a server's spare) gives the
  // recogniser the same phones as one it loads itself, phone for phone; one prepared for other
  // options is not used.
  const auto wav =
      std::filesystem::temp_directory_path() / ("live_audio_test-ahead-" + std::to_string(::getpid()) + ".wav");
  const auto recording = testing::flite_recording("Papa bought five more big maps.", wav);
  std::filesystem::remove(wav);
  ASSERT_TRUE(recording);
  PcmAudio audio = recording->audio;
  audio.samples.insert(audio.samples.end(), static_cast<std::size_t>(audio.sample_rate_hz), 0);
  audio.samples.insert(audio.samples.end(), recording->audio.samples.begin(), recording->audio.samples.end());
  for (const bool with_transcript : {true, false}) {
    SCOPED_TRACE(with_transcript ? "with the transcript" : "from the audio alone");
    LiveRecognitionOptions options;
    if (with_transcript) options.transcript = "Papa bought five more big maps.";
    options.sample_rate_hz = audio.sample_rate_hz;
    LiveRecognizer loading(options, "live");
    const std::vector<LabeledInterval> loaded = recognise_in_pieces(audio, loading);
    PreparedLiveDecoder prepared;
    std::thread([&] { prepared = prepare_live_decoder(options, "ahead"); }).join();
    ASSERT_TRUE(prepared);
    LiveRecognizer ahead(options, "live", std::move(prepared));
    const std::vector<LabeledInterval> heard = recognise_in_pieces(audio, ahead);
    ASSERT_EQ(heard.size(), loaded.size());
    for (std::size_t i = 0; i < heard.size(); ++i) {
      EXPECT_EQ(heard[i].label, loaded[i].label) << "phone " << i;
      EXPECT_EQ(heard[i].start_us, loaded[i].start_us) << "phone " << i;
      EXPECT_EQ(heard[i].end_us, loaded[i].end_us) << "phone " << i;
    }
    // Both sentences were heard (about 20 phones each).
    EXPECT_GE(std::count_if(heard.begin(), heard.end(), [](const LabeledInterval& p) { return !p.label.empty(); }), 30);
    // A decoder of the other kind is not taken (it would decode with the wrong search).
    LiveRecognitionOptions other = options;
    other.transcript = with_transcript ? std::nullopt : std::optional<std::string>("Papa bought five more big maps.");
    EXPECT_FALSE(same_live_decoder(other, options));
    LiveRecognizer mismatched(options, "live", prepare_live_decoder(other, "other"));
    const std::vector<LabeledInterval> again = recognise_in_pieces(audio, mismatched);
    ASSERT_EQ(again.size(), loaded.size());
    for (std::size_t i = 0; i < again.size(); ++i) EXPECT_EQ(again[i].label, loaded[i].label) << "phone " << i;
  }
}

/// The bilabials of `truth` (the synthesiser's phones) that `heard` labels /p b m/ at their middles.
testing::BoundaryScore closures_of(const testing::Recording& truth, const std::vector<LabeledInterval>& heard) {
  const ArticulationModel& model = ArticulationModel::builtin();
  LabeledUtterance utterance;
  utterance.phone_set = "arpabet";
  utterance.intervals = heard;
  testing::BoundaryScore score;
  testing::score_alignment(truth.phonemes, *PhoneSet::builtin("radio", model), utterance,
                           *PhoneSet::builtin("arpabet", model), model, score);
  return score;
}

TEST(LiveRecognizer, WordsThatComeOnlyAsTheyAreSpokenAreDecodedAgainAndCloseTheLipsAsTheWholeTranscriptDoes) {
  // A TTS that hands out each word just as its audio starts (the latest a transcript can come):
  // the stream starts with an empty transcript, so each utterance opens on the phone loop and
  // runs out of words again and again; each time it is decoded again with the words known. The
  // phones tile the audio and Festival's own /p b m/ (Harvard sentences 21-25) are labelled
  // /p b m/ at their middles as often as with the whole transcript given first.
  const auto wav =
      std::filesystem::temp_directory_path() / ("live_audio_test-grow-" + std::to_string(::getpid()) + ".wav");
  testing::BoundaryScore growing, whole;
  std::size_t redecodes = 0;
  for (std::size_t s = 20; s < 25; ++s) {
    const char* sentence = testing::kHarvardSentences[s];
    SCOPED_TRACE(sentence);
    const auto recording = testing::festival_recording(sentence, wav);
    const std::vector<TimedWord> words = testing::festival_word_starts(sentence);
    ASSERT_TRUE(recording);
    ASSERT_FALSE(words.empty());
    LiveRecognitionOptions options;
    options.sample_rate_hz = recording->audio.sample_rate_hz;
    options.transcript = sentence;
    LiveRecognizer given_first(options, "live");
    const testing::BoundaryScore with_whole =
        closures_of(*recording, recognise_in_pieces(recording->audio, given_first));
    whole.bilabials += with_whole.bilabials;
    whole.bilabials_closed_at_middle += with_whole.bilabials_closed_at_middle;

    options.transcript = "";
    LiveRecognizer as_spoken(options, "live");
    std::size_t next = 0;
    const std::vector<LabeledInterval> phones =
        recognise_in_pieces(recording->audio, as_spoken, [&](std::int64_t piece_end_us) {
          for (; next < words.size() && words[next].start_us < piece_end_us; ++next)
            as_spoken.add_words(words[next].text);
        });
    expect_tiles(phones, recording->audio.duration_us());
    const testing::BoundaryScore with_growing = closures_of(*recording, phones);
    growing.bilabials += with_growing.bilabials;
    growing.bilabials_closed_at_middle += with_growing.bilabials_closed_at_middle;
    redecodes += as_spoken.redecodes();
  }
  std::filesystem::remove(wav);
  std::cerr << "closed at their middles: " << growing.bilabials_closed_at_middle << " of " << growing.bilabials
            << " with the words as spoken (" << redecodes << " decodes again), " << whole.bilabials_closed_at_middle
            << " with the whole transcript first\n";
  EXPECT_GT(redecodes, 5U);
  EXPECT_GE(growing.bilabials_closed_at_middle * 10, growing.bilabials * 9);
  EXPECT_GE(growing.bilabials_closed_at_middle + 1, whole.bilabials_closed_at_middle);
}

TEST(LiveRecognizer, TimedWordsPlaceAnUtteranceInTheTranscriptAfterSpeechThatDidNotFollowIt) {
  // Festival speaks Harvard sentence 26, a second of silence, then sentence 23; the transcript's
  // first words are two other sentences (a TTS that normalised its text differently from what it
  // was given), then sentence 23's. Without times the second utterance starts wherever the forced
  // alignment of the first left off, inside the wrong words, and must pass through the rest of
  // them; with the TTS's times it starts at sentence 23's first word, and more of its phones are
  // heard as they were spoken.
  const auto wav =
      std::filesystem::temp_directory_path() / ("live_audio_test-timed-" + std::to_string(::getpid()) + ".wav");
  const char* spoken_first = testing::kHarvardSentences[25];
  const char* spoken_second = testing::kHarvardSentences[22];
  const auto first = testing::festival_recording(spoken_first, wav);
  const auto second = testing::festival_recording(spoken_second, wav);
  std::filesystem::remove(wav);
  const std::vector<TimedWord> second_words = testing::festival_word_starts(spoken_second);
  ASSERT_TRUE(first && second);
  ASSERT_FALSE(second_words.empty());
  PcmAudio audio = first->audio;
  audio.samples.insert(audio.samples.end(), static_cast<std::size_t>(audio.sample_rate_hz), 0);
  const std::int64_t second_start_us = audio.duration_us();
  audio.samples.insert(audio.samples.end(), second->audio.samples.begin(), second->audio.samples.end());
  testing::Recording second_truth = *second;
  for (LabeledInterval& phone : second_truth.phonemes.intervals) {
    phone.start_us += second_start_us;
    phone.end_us += second_start_us;
  }
  std::vector<TimedWord> transcript;
  std::int64_t at_us = 200'000;
  for (const std::string word : {"a", "large", "size", "in", "stockings", "is", "hard", "to", "sell", "the", "boy",
                                 "was", "there", "when", "the", "sun", "rose"}) {
    transcript.push_back({word, at_us});
    at_us += 120'000;  // (a TTS in a hurry: all before the second sentence)
  }
  for (const TimedWord& word : second_words) transcript.push_back({word.text, word.start_us + second_start_us});

  const auto closed_in_second = [&](bool timed) {
    LiveRecognitionOptions options;
    options.sample_rate_hz = audio.sample_rate_hz;
    options.transcript = "";
    LiveRecognizer recognizer(options, "live");
    if (timed) {
      recognizer.add_timed_words(transcript);
    } else {
      for (const TimedWord& word : transcript) recognizer.add_words(word.text);
    }
    const std::vector<LabeledInterval> phones = recognise_in_pieces(audio, recognizer);
    expect_tiles(phones, audio.duration_us());
    EXPECT_EQ(recognizer.utterances(), 2U);
    return closures_of(second_truth, phones);
  };
  const testing::BoundaryScore timed = closed_in_second(true);
  const testing::BoundaryScore untimed = closed_in_second(false);
  std::cerr << "sentence 23's phones heard as spoken: " << timed.matched_phonemes << " of " << timed.reference_phonemes
            << " with times, " << untimed.matched_phonemes
            << " without; its bilabials closed at their middles: " << timed.bilabials_closed_at_middle << " of "
            << timed.bilabials << " with times, " << untimed.bilabials_closed_at_middle << " without\n";
  EXPECT_GT(timed.matched_phonemes, untimed.matched_phonemes);
  EXPECT_GE(timed.matched_phonemes * 4, timed.reference_phonemes * 3);
  EXPECT_GE(timed.bilabials_closed_at_middle, untimed.bilabials_closed_at_middle);
}

TEST(LiveRecognizer, RefusesWordsItCannotPlaceNamingThem) {
  LiveRecognitionOptions options;
  LiveRecognizer without(options, "settings");
  EXPECT_EQ(error_of([&] { without.add_words("papa"); }),
            "settings: word 'papa' given to a stream without a transcript (a stream whose words come later starts "
            "with an empty transcript)");
  options.transcript = "papa bought";
  LiveRecognizer with(options, "words");
  EXPECT_EQ(error_of([&] { with.add_words("five zqxwv maps"); }),
            "words: transcript word 4 'zqxwv' is not in the pronouncing dictionary (write numbers and abbreviations "
            "out as words)");
  EXPECT_EQ(with.words_ahead(), 3U);  // the words before it were added
  const std::vector<TimedWord> timed = {{"big", 900'000}, {"maps", 800'000}};
  EXPECT_EQ(error_of([&] { with.add_timed_words(timed); }),
            "words: timed word 5 'maps' starts at 800000 us, before the word before it (900000 us): timed words come "
            "in the order they are spoken, on the stream's clock");
  const std::vector<TimedWord> punctuation = {{"--", 1'000'000}};
  EXPECT_EQ(error_of([&] { with.add_timed_words(punctuation); }), "words: timed word 5 '--' has no letters or digits");
}

TEST(LiveRecognizer, RefusesWhatItCannotHearNamingIt) {
  LiveRecognitionOptions options;
  options.sample_rate_hz = 4000;
  EXPECT_EQ(error_of([&] { LiveRecognizer recognizer(options, "settings"); }),
            "settings: sample rate 4000 Hz: live audio takes 8000 to 48000 Hz");
  options.sample_rate_hz = 16000;
  options.transcript = "the zqxwv parked";
  EXPECT_EQ(error_of([&] { LiveRecognizer recognizer(options, "settings.transcript"); }),
            "settings.transcript: transcript word 2 'zqxwv' is not in the pronouncing dictionary (write numbers and "
            "abbreviations out as words)");
}

}  // namespace
}  // namespace lipsync::speech
