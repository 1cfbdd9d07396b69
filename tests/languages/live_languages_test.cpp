// Live audio in other languages with a transcript: LiveSynthesisAligner warps the audio, as it
// arrives in 20 ms pieces, against espeak-ng's rendering of the transcript
// (lipsync/speech/live_synthesis_aligner.hpp), on Festival's Italian, Czech and Finnish recordings of
// tests/data/recorded_languages, whose own segment times are the truth.
//
// - At every piece the phones taken and the guess tile the audio heard; the final phones tile the
//   whole stream at its end; a phone, once final, is not taken back (take_final only appends).
// - At the middle of each bilabial closure Festival spoke, the final phone is a bilabial, for at
//   least 90 % of them (the live path's goal with a transcript, docs/streaming.md).
// - Two sentences with a second and a half of silence between them: the silence is final silence,
//   and their closures are heard as when each is heard alone (one fewer at most), with the whole
//   transcript first and with each sentence's words sent only as it starts (a TTS's sentence at a
//   time).
// - Words that come one at a time, a second ahead of their speech: the unheard rest of their
//   sentence is spoken again with each part that continues it, and 80 % of the closures are heard
//   (the whole transcript ahead: all but one). The rest spoken again is 40 words at most.
// - A transcript of 16 KiB is spoken by espeak-ng a few sentences ahead of the speech, not whole
//   before the first piece; a stream of three minutes drops what it has heard and hears its last
//   sentence as its first.
// - A minute of silence after the speech keeps the window (the audio the aligner holds) as short as
//   the commit delay; audio with no words to hear is silence, and a note says so.
// - Words with times (a TTS's marks) place the speech after a pause: a sentence after another
//   sentence's audio (or after noise), with its own words alone, timed, shows its closures as it
//   does alone, after a pause of 1.5 s or of 300 ms; the same words untimed leave it silent (after
//   noise: half its closures at most).
//   Two sentences whose speech follows their timed words show the closures they show untimed.
// - Bad input: an unknown voice, a sample rate outside 8000-48000; timed words before 0, out of
//   order or without letters, each naming the word as the English recogniser does.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <utility>

#include "../support/recorded_languages.hpp"
#include "lipsync/error.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/live_synthesis_aligner.hpp"
#include "lipsync/word_marks.hpp"

namespace lipsync::speech {
namespace {

using ::testing::HasSubstr;

using Item = testing::RecordedLanguage;
using testing::speech_span_us;
using testing::timed_words_of;

Item load(const std::string& name) { return testing::recorded_language(name); }

bool is_bilabial(const std::string& label) {
  // espeak-ng's Catalan and Spanish /b/ between vowels is /β/, shown as a /b/.
  return label.starts_with("p") || label.starts_with("b") || label.starts_with("m") || label.starts_with("β");
}

/// What a live stream gave: its final phones and its notes.
struct Heard {
  std::vector<LabeledInterval> phones;
  std::vector<std::string> notes;
};

void expect_tiles(const std::vector<LabeledInterval>& phones, std::int64_t from_us, std::int64_t to_us,
                  const std::string& what) {
  std::int64_t at = from_us;
  for (const LabeledInterval& phone : phones) {
    ASSERT_EQ(phone.start_us, at) << what;
    ASSERT_GT(phone.end_us, phone.start_us) << what;
    at = phone.end_us;
  }
  ASSERT_EQ(at, to_us) << what;
}

/// Pushes `audio` in 20 ms pieces; `before_piece(at_us)` may add words before each piece.
template <class BeforePiece>
Heard listen(LiveSynthesisAligner& aligner, const PcmAudio& audio, BeforePiece before_piece) {
  Heard heard;
  const std::size_t piece = static_cast<std::size_t>(audio.sample_rate_hz / 50);
  for (std::size_t at = 0; at < audio.samples.size(); at += piece) {
    before_piece(static_cast<std::int64_t>(at) * 1'000'000 / audio.sample_rate_hz);
    aligner.push(std::span(audio.samples).subspan(at, std::min(piece, audio.samples.size() - at)));
    for (LabeledInterval& phone : aligner.take_final()) heard.phones.push_back(std::move(phone));
    const std::int64_t taken_us = heard.phones.empty() ? 0 : heard.phones.back().end_us;
    expect_tiles(aligner.guess(), taken_us, aligner.heard_us(), "the guess at " + std::to_string(at));
  }
  aligner.finish();
  for (LabeledInterval& phone : aligner.take_final()) heard.phones.push_back(std::move(phone));
  EXPECT_TRUE(aligner.guess().empty());
  heard.notes = aligner.take_notes();
  return heard;
}

Heard listen(LiveSynthesisAligner& aligner, const PcmAudio& audio) {
  return listen(aligner, audio, [](std::int64_t) {});
}

std::string label_at(const std::vector<LabeledInterval>& phones, std::int64_t t_us) {
  for (const LabeledInterval& phone : phones) {
    if (phone.start_us <= t_us && t_us < phone.end_us) return phone.label;
  }
  return "(none)";
}

/// Counts the closures of `middles_us` (shifted by `offset_us`) heard as a bilabial at their middle.
int closed_at(const std::vector<LabeledInterval>& phones, const std::vector<std::int64_t>& middles_us,
              std::int64_t offset_us, const std::string& name) {
  int closed = 0;
  for (const std::int64_t middle_us : middles_us) {
    const std::string label = label_at(phones, offset_us + middle_us);
    if (is_bilabial(label)) {
      ++closed;
    } else {
      std::cerr << "  " << name << ": closure's middle at " << offset_us + middle_us << " us heard as '" << label
                << "'\n";
    }
  }
  return closed;
}

LiveSynthesisOptions options_for(const Item& item) {
  LiveSynthesisOptions options;
  options.transcript = item.transcript;
  options.synthesis.voice = item.voice;
  options.sample_rate_hz = item.audio.sample_rate_hz;
  return options;
}

TEST(LiveLanguages, FestivalsClosuresAreHeardLiveInEveryLanguageOfTheCorpus) {
  int bilabials = 0, closed = 0;
  for (const char* name : {"it_3", "cs_1", "ca_1", "cs_2", "hi_3", "it_1", "fi_2"}) {
    SCOPED_TRACE(name);
    const Item item = load(name);
    LiveSynthesisAligner aligner(options_for(item), name);
    const Heard heard = listen(aligner, item.audio);
    expect_tiles(heard.phones, 0, item.audio.duration_us(), name);
    bilabials += static_cast<int>(item.bilabial_middles_us.size());
    closed += closed_at(heard.phones, item.bilabial_middles_us, 0, name);
  }
  std::cerr << "live warp: " << closed << " of " << bilabials << " closures heard as bilabials\n";
  ASSERT_GT(bilabials, 30);
  EXPECT_GE(closed * 10, bilabials * 9) << closed << " of " << bilabials;
}

/// it_1, 1.5 s of silence, it_3, and the transcripts of both.
struct TwoSentences {
  Item first, second;
  PcmAudio audio;
  std::int64_t second_at_us = 0;
};

TwoSentences two_sentences() {
  TwoSentences both{load("it_1"), load("it_3"), {}, 0};
  both.audio = both.first.audio;
  both.audio.samples.resize(both.audio.samples.size() + static_cast<std::size_t>(both.audio.sample_rate_hz) * 3 / 2, 0);
  both.second_at_us = both.audio.duration_us();
  both.audio.samples.insert(both.audio.samples.end(), both.second.audio.samples.begin(),
                            both.second.audio.samples.end());
  return both;
}

/// The closures of `item` heard at their middles when it is heard alone.
int closed_alone(const Item& item, const std::string& name) {
  LiveSynthesisAligner aligner(options_for(item), name);
  return closed_at(listen(aligner, item.audio).phones, item.bilabial_middles_us, 0, name + " alone");
}

TEST(LiveLanguages, WordsThatComeOneAtATimeASecondAheadOfTheirSpeechAreSpokenWithTheRestOfTheirSentence) {
  // A TTS's word marks come a word at a time, a second or so ahead of the word's audio. The words
  // of a sentence wait for its end while the rendering reaches past the speech, and each part
  // spoken before the end is spoken again, from its first word the speech has not reached, with
  // the words that continue it: so the sentence is not rendered as a string of one-word sentences
  // (each with a pause and a falling end the speech does not have). 37 of the 43 closures are
  // heard; waiting alone heard 29, speaking each word as it came 21; the whole transcript ahead, 42.
  int bilabials = 0, closed = 0, closed_whole = 0;
  std::size_t respoken = 0;
  for (const char* name : {"it_3", "cs_1", "ca_1", "cs_2", "hi_3", "it_1", "fi_2"}) {
    SCOPED_TRACE(name);
    const Item item = load(name);
    const std::vector<TimedWord> words = timed_words_of(item, 0);
    LiveSynthesisOptions options = options_for(item);
    options.transcript = "";
    LiveSynthesisAligner aligner(options, name);
    std::size_t next = 0;
    const Heard heard = listen(aligner, item.audio, [&](std::int64_t at_us) {
      for (; next < words.size() && words[next].start_us < at_us + 20'000 + 1'000'000; ++next) {
        aligner.add_words(words[next].text);
      }
    });
    expect_tiles(heard.phones, 0, item.audio.duration_us(), name);
    respoken += aligner.respoken();
    bilabials += static_cast<int>(item.bilabial_middles_us.size());
    closed += closed_at(heard.phones, item.bilabial_middles_us, 0, name + std::string(", a word at a time"));
    closed_whole += closed_alone(item, name);
  }
  std::cerr << "words a second ahead, one at a time: " << closed << " of " << bilabials
            << " closures heard as bilabials; with the whole transcript: " << closed_whole << "; parts spoken again "
            << respoken << "\n";
  EXPECT_GT(respoken, 0U);
  EXPECT_GE(closed * 10, bilabials * 8) << closed << " of " << bilabials;
}

TEST(LiveLanguages, AnOpenSentenceIsSpokenAgainWithItsNextWordsUpToFortyWords) {
  // Nothing heard yet: the anchor is at the first word, so every word of an open sentence is unheard.
  const Item item = load("it_1");
  LiveSynthesisOptions options = options_for(item);
  options.transcript = "mamma posso avere un panino";  // no full stop: the sentence stays open
  // Its end comes: the five words are spoken again with the four that end it.
  LiveSynthesisAligner short_sentence(options, "short");
  const std::size_t phones_before = short_sentence.rendering_phones();
  short_sentence.add_words("con burro e marmellata.");
  EXPECT_EQ(short_sentence.respoken(), 1U);
  // Spoken as one sentence, as the whole of it is: not with a pause and a falling end after "panino".
  options.transcript += " con burro e marmellata.";
  LiveSynthesisAligner whole(options, "whole");
  EXPECT_GT(short_sentence.rendering_phones(), phones_before);
  EXPECT_EQ(short_sentence.rendering_phones(), whole.rendering_phones());

  std::string long_text;
  for (int k = 0; k < 9; ++k) long_text += "mamma posso avere un panino ";  // 45 words
  options.transcript = long_text;
  LiveSynthesisAligner long_sentence(options, "long");
  const std::size_t long_before = long_sentence.rendering_phones();
  long_sentence.add_words("con burro e marmellata.");
  EXPECT_EQ(long_sentence.respoken(), 0U);
  EXPECT_GT(long_sentence.rendering_phones(), long_before);
  // A sentence ended is not spoken again: the next one is spoken after it.
  const std::size_t ended_at = long_sentence.rendering_phones();
  long_sentence.add_words("grazie.");
  EXPECT_EQ(long_sentence.respoken(), 0U);
  EXPECT_GT(long_sentence.rendering_phones(), ended_at);
}

TEST(LiveLanguages, APauseBetweenSentencesIsSilenceAndTheNextSentenceIsHeardAsTheFirst) {
  const TwoSentences both = two_sentences();
  LiveSynthesisOptions options = options_for(both.first);
  options.transcript = both.first.transcript + " " + both.second.transcript;
  LiveSynthesisAligner aligner(options, "two sentences");
  const Heard heard = listen(aligner, both.audio);
  expect_tiles(heard.phones, 0, both.audio.duration_us(), "two sentences");
  // The middle of the pause is silence.
  EXPECT_EQ(label_at(heard.phones, both.second_at_us - 700'000), "");
  // Each sentence's closures as it shows them alone, give or take one (the warp after the pause
  // starts from other means than a stream's first sentence).
  const int closed = closed_at(heard.phones, both.first.bilabial_middles_us, 0, "it_1") +
                     closed_at(heard.phones, both.second.bilabial_middles_us, both.second_at_us, "it_3");
  const int alone = closed_alone(both.first, "it_1") + closed_alone(both.second, "it_3");
  EXPECT_GE(closed, alone - 1) << closed << " closures heard in the two sentences, " << alone << " alone";
}

TEST(LiveLanguages, WordsSentAsTheirSentenceStartsAreHeardAsAWholeTranscriptIs) {
  const TwoSentences both = two_sentences();
  LiveSynthesisOptions options = options_for(both.first);
  options.transcript = "";
  LiveSynthesisAligner aligner(options, "sentence by sentence");
  bool first_sent = false, second_sent = false;
  const Heard heard = listen(aligner, both.audio, [&](std::int64_t at_us) {
    if (!first_sent) {
      aligner.add_words(both.first.transcript);
      first_sent = true;
    }
    if (!second_sent && at_us >= both.second_at_us - 200'000) {
      aligner.add_words(both.second.transcript);
      second_sent = true;
    }
  });
  expect_tiles(heard.phones, 0, both.audio.duration_us(), "sentence by sentence");
  const int closed = closed_at(heard.phones, both.first.bilabial_middles_us, 0, "it_1") +
                     closed_at(heard.phones, both.second.bilabial_middles_us, both.second_at_us, "it_3");
  const int alone = closed_alone(both.first, "it_1") + closed_alone(both.second, "it_3");
  EXPECT_GE(closed, alone - 1) << closed << " closures heard sentence by sentence, " << alone << " alone";
}

TEST(LiveLanguages, AMinuteOfSilenceKeepsTheWindowShortAndAudioWithoutWordsIsSilence) {
  const Item item = load("cs_1");
  LiveSynthesisAligner aligner(options_for(item), "cs_1 and silence");
  PcmAudio audio = item.audio;
  audio.samples.resize(audio.samples.size() + static_cast<std::size_t>(audio.sample_rate_hz) * 60, 0);
  // Then the speech again: the transcript is spoken out, so it is shown as silence.
  audio.samples.insert(audio.samples.end(), item.audio.samples.begin(), item.audio.samples.end());
  std::int64_t longest_window_us = 0;
  const std::int64_t silence_from_us = item.audio.duration_us() + 2'000'000;
  const Heard heard = listen(aligner, audio, [&](std::int64_t at_us) {
    if (at_us > silence_from_us) longest_window_us = std::max(longest_window_us, at_us - aligner.final_us());
  });
  expect_tiles(heard.phones, 0, audio.duration_us(), "cs_1 and silence");
  EXPECT_LE(longest_window_us, 800'000);
  EXPECT_EQ(label_at(heard.phones, item.audio.duration_us() + 30'000'000), "");
  EXPECT_EQ(label_at(heard.phones, audio.duration_us() - item.audio.duration_us() / 2), "");
  EXPECT_THAT(heard.notes, ::testing::Contains(HasSubstr("after the transcript's last word is shown as silence")));
}

TEST(LiveLanguages, ALongTranscriptIsSpokenAFewSentencesAheadOfTheSpeech) {
  // 16 KiB of words (a quarter of an hour of speech) are spoken by espeak-ng a few sentences at a
  // time, as the speech nears them, not all before the first piece of audio.
  const Item item = load("it_3");
  LiveSynthesisOptions options = options_for(item);
  options.transcript.clear();
  while (options.transcript.size() + item.transcript.size() < 16 * 1024) options.transcript += item.transcript + " ";
  const std::size_t sentences = options.transcript.size() / (item.transcript.size() + 1);
  LiveSynthesisAligner aligner(options, "a long transcript");
  EXPECT_EQ(aligner.words_ahead(), sentences * 10);
  const std::size_t spoken_at_start = aligner.rendering_phones();
  EXPECT_GT(spoken_at_start, 0u);
  EXPECT_LT(spoken_at_start * 10, sentences * 45);  // under a tenth of the sentences' phones
  // Its first sentence is heard as it is heard alone.
  const Heard heard = listen(aligner, item.audio);
  EXPECT_EQ(closed_at(heard.phones, item.bilabial_middles_us, 0, "it_3 of many"), closed_alone(item, "it_3"));
}

TEST(LiveLanguages, AStreamOfMinutesDropsWhatItHasHeardAndItsLastSentenceIsHeardAsTheFirst) {
  // Forty-five times the same sentence, three minutes of speech, with its transcript: the rendering
  // behind the anchor is dropped as the stream goes (past two minutes), and the last sentence's
  // closures are heard as the first's.
  const Item item = load("it_3");
  LiveSynthesisOptions options = options_for(item);
  options.transcript.clear();
  PcmAudio audio{item.audio.sample_rate_hz, {}};
  constexpr int kTimes = 45;
  for (int k = 0; k < kTimes; ++k) {
    options.transcript += item.transcript + " ";
    audio.samples.insert(audio.samples.end(), item.audio.samples.begin(), item.audio.samples.end());
    audio.samples.resize(audio.samples.size() + static_cast<std::size_t>(audio.sample_rate_hz) / 2, 0);
  }
  LiveSynthesisAligner aligner(options, "minutes");
  const Heard heard = listen(aligner, audio);
  expect_tiles(heard.phones, 0, audio.duration_us(), "minutes");
  const auto rate = static_cast<std::int64_t>(item.audio.sample_rate_hz);
  const std::int64_t last_at_us =
      (kTimes - 1) * (static_cast<std::int64_t>(item.audio.samples.size()) + rate / 2) * 1'000'000 / rate;
  EXPECT_EQ(closed_at(heard.phones, item.bilabial_middles_us, last_at_us, "it_3, the last"),
            closed_at(heard.phones, item.bilabial_middles_us, 0, "it_3, the first"));
  EXPECT_EQ(aligner.words_ahead(), 0u);
  EXPECT_GT(aligner.rendering_frames(), 12'000u);  // over two minutes of espeak-ng
  EXPECT_LT(aligner.rendering_frames_held(), 10'000u);
}

/// Audio the words do not describe (`before`), `silence_us` of silence (1.5 s), then `item`, whose
/// words alone are the transcript (sent before the audio, with their times or without).
struct AfterOtherAudio {
  PcmAudio audio;
  std::int64_t item_at_us = 0;
};

AfterOtherAudio after_other_audio(const PcmAudio& before, const Item& item, std::int64_t silence_us = 1'500'000) {
  AfterOtherAudio both{before, 0};
  both.audio.samples.resize(
      both.audio.samples.size() + static_cast<std::size_t>(silence_us * both.audio.sample_rate_hz / 1'000'000), 0);
  both.item_at_us = both.audio.duration_us();
  both.audio.samples.insert(both.audio.samples.end(), item.audio.samples.begin(), item.audio.samples.end());
  return both;
}

/// `audio` from `from_us` to `to_us`.
PcmAudio cut(const PcmAudio& audio, std::int64_t from_us, std::int64_t to_us) {
  const auto sample = [&](std::int64_t us) {
    return audio.samples.begin() + static_cast<std::ptrdiff_t>(us * audio.sample_rate_hz / 1'000'000);
  };
  return PcmAudio{audio.sample_rate_hz, std::vector<std::int16_t>(sample(from_us), sample(to_us))};
}

/// The closures of `item` heard at their middles in `both`, its words sent before the audio with
/// their times or without.
int closed_after_other_audio(const AfterOtherAudio& both, const Item& item, bool timed, const std::string& name) {
  LiveSynthesisOptions options = options_for(item);
  options.transcript = "";
  LiveSynthesisAligner aligner(options, name);
  if (timed) {
    aligner.add_timed_words(timed_words_of(item, both.item_at_us));
  } else {
    aligner.add_words(item.transcript);
  }
  const Heard heard = listen(aligner, both.audio);
  expect_tiles(heard.phones, 0, both.audio.duration_us(), name);
  return closed_at(heard.phones, item.bilabial_middles_us, both.item_at_us, name);
}

TEST(LiveLanguages, WordTimesPlaceTheSpeechAfterAPauseSoSpeechTheWordsDoNotDescribeDoesNotDragTheRest) {
  // One sentence's audio, then another's, with the second's words alone: the warp hears the first
  // as the second's words. With the words' times, the second's speech after the pause is warped
  // from its first word again, and its closures are heard as when it is heard alone; without them
  // the warp has spent the words on the first sentence, and the second is silence.
  for (const auto& [other_name, name] : {std::pair{"it_1", "it_3"}, {"cs_1", "cs_2"}, {"cs_2", "cs_1"}}) {
    SCOPED_TRACE(name);
    const Item other = load(other_name);
    const Item item = load(name);
    const AfterOtherAudio both = after_other_audio(other.audio, item);
    const int alone = closed_alone(item, name);
    const int timed = closed_after_other_audio(both, item, true, std::string(name) + " after speech, timed");
    const int untimed = closed_after_other_audio(both, item, false, std::string(name) + " after speech, untimed");
    std::cerr << name << " after " << other_name << ": " << timed << " closures with times, " << untimed << " without, "
              << alone << " alone, of " << item.bilabial_middles_us.size() << "\n";
    EXPECT_EQ(timed, alone);
    EXPECT_EQ(untimed, 0);
  }
}

TEST(LiveLanguages, WordTimesPlaceTheSpeechAfterAShortPauseToo) {
  // As above with the recordings' own silences cut, 300 ms of pause between the speech: the pause
  // is cut from the window while the speech before it is still there, and the speech after it is
  // warped from the timed word as after a long one.
  for (const auto& [other_name, name] : {std::pair{"it_1", "it_3"}, {"cs_1", "cs_2"}}) {
    SCOPED_TRACE(name);
    const Item other = load(other_name);
    Item item = load(name);
    const std::int64_t item_from_us = speech_span_us(item.audio).first - 50'000;
    item.audio = cut(item.audio, item_from_us, item.audio.duration_us());
    for (std::int64_t& middle_us : item.bilabial_middles_us) middle_us -= item_from_us;
    const AfterOtherAudio both =
        after_other_audio(cut(other.audio, 0, speech_span_us(other.audio).second), item, 250'000);
    const int alone = closed_alone(item, name);
    const int timed = closed_after_other_audio(both, item, true, std::string(name) + " after a short pause, timed");
    const int untimed =
        closed_after_other_audio(both, item, false, std::string(name) + " after a short pause, untimed");
    std::cerr << name << " 300 ms after " << other_name << ": " << timed << " closures with times, " << untimed
              << " without, " << alone << " alone, of " << item.bilabial_middles_us.size() << "\n";
    EXPECT_EQ(timed, alone);
    EXPECT_EQ(untimed, 0);
  }
}

/// `duration_us` of white noise at `rms` (of full scale), the same every run.
PcmAudio noise(int rate_hz, std::int64_t duration_us, double rms) {
  std::mt19937 random(7);
  std::normal_distribution<double> normal(0.0, rms * 32767.0);
  PcmAudio audio{rate_hz, std::vector<std::int16_t>(static_cast<std::size_t>(duration_us * rate_hz / 1'000'000))};
  for (std::int16_t& sample : audio.samples)
    sample = static_cast<std::int16_t>(std::clamp(normal(random), -32767.0, 32767.0));
  return audio;
}

TEST(LiveLanguages, WordTimesPlaceTheSpeechAfterAPauseThatFollowsNoise) {
  // Two seconds of white noise (at a twentieth of full scale), the pause, then the sentence:
  // with the times its closures are heard as alone; without them the warp has matched the noise
  // to its first words, and fewer than half are heard.
  for (const char* name : {"it_3", "cs_2"}) {
    SCOPED_TRACE(name);
    const Item item = load(name);
    const AfterOtherAudio both = after_other_audio(noise(item.audio.sample_rate_hz, 2'000'000, 0.05), item);
    const int alone = closed_alone(item, name);
    const int timed = closed_after_other_audio(both, item, true, std::string(name) + " after noise, timed");
    const int untimed = closed_after_other_audio(both, item, false, std::string(name) + " after noise, untimed");
    std::cerr << name << " after noise: " << timed << " closures with times, " << untimed << " without, " << alone
              << " alone, of " << item.bilabial_middles_us.size() << "\n";
    EXPECT_EQ(timed, alone);
    EXPECT_LE(untimed * 2, alone);
  }
}

TEST(LiveLanguages, WordTimesOfSpeechThatFollowsTheWordsShowTheSameClosures) {
  // The two sentences with the pause between, the words of both sent before the audio with their
  // times: the second is warped from its first word after the pause, where the warp had come
  // anyway, and both show the closures they show with the same words untimed.
  const TwoSentences both = two_sentences();
  LiveSynthesisOptions options = options_for(both.first);
  options.transcript = "";
  std::vector<TimedWord> words = timed_words_of(both.first, 0);
  const std::vector<TimedWord> second = timed_words_of(both.second, both.second_at_us);
  words.insert(words.end(), second.begin(), second.end());
  const auto closed = [&](const std::vector<LabeledInterval>& phones) {
    return closed_at(phones, both.first.bilabial_middles_us, 0, "it_1") +
           closed_at(phones, both.second.bilabial_middles_us, both.second_at_us, "it_3");
  };
  LiveSynthesisAligner timed(options, "two sentences, timed");
  timed.add_timed_words(words);
  const Heard heard_timed = listen(timed, both.audio);
  expect_tiles(heard_timed.phones, 0, both.audio.duration_us(), "two sentences, timed");
  LiveSynthesisAligner untimed(options, "two sentences, untimed");
  untimed.add_words(both.first.transcript + " " + both.second.transcript);
  const Heard heard_untimed = listen(untimed, both.audio);
  const int closed_timed = closed(heard_timed.phones);
  const int closed_untimed = closed(heard_untimed.phones);
  std::cerr << "two sentences: " << closed_timed << " closures with times, " << closed_untimed << " without\n";
  EXPECT_EQ(closed_timed, closed_untimed);
  EXPECT_EQ(label_at(heard_timed.phones, both.second_at_us - 700'000), "");
}

TEST(LiveLanguages, BadWordTimesAreErrorsNamingTheWord) {
  const Item item = load("it_3");
  LiveSynthesisOptions options = options_for(item);
  options.transcript = "";
  LiveSynthesisAligner aligner(options, "settings.transcript");
  const auto refused = [&](const std::vector<TimedWord>& words) {
    try {
      aligner.add_timed_words(words);
    } catch (const InputError& error) {
      return std::string(error.message());
    }
    return std::string("(accepted)");
  };
  EXPECT_EQ(refused({{"La", -5}}),
            "timed word 1 'La' starts at -5 us, before the word before it (0 us): timed words come in the order "
            "they are spoken, on the stream's clock");
  EXPECT_EQ(refused({{"La", 0}, {"mamma", 200'000}, {"compra", 100'000}}),
            "timed word 3 'compra' starts at 100000 us, before the word before it (200000 us): timed words come in "
            "the order they are spoken, on the stream's clock");
  EXPECT_EQ(refused({{"La", 0}, {"--", 100'000}}), "timed word 2 '--' has no letters or digits");
  EXPECT_EQ(aligner.words_ahead(), 0u);  // nothing of a refused message is added
  // Later messages go on from the last time given.
  EXPECT_EQ(refused({{"La", 300'000}, {"mamma", 400'000}}), "(accepted)");
  EXPECT_EQ(refused({{"compra", 350'000}}),
            "timed word 3 'compra' starts at 350000 us, before the word before it (400000 us): timed words come in "
            "the order they are spoken, on the stream's clock");
  EXPECT_EQ(aligner.words_ahead(), 2u);
}

TEST(LiveLanguages, BadSettingsAreErrorsNamingWhatIsWrong) {
  LiveSynthesisOptions options;
  options.transcript = "La mamma compra le mele.";
  options.synthesis.voice = "zz-nonesuch";
  try {
    LiveSynthesisAligner aligner(options, "settings.transcript");
    FAIL() << "an unknown voice was accepted";
  } catch (const InputError& error) {
    EXPECT_THAT(error.what(), HasSubstr("unknown voice 'zz-nonesuch'"));
  }
  options.synthesis.voice = "it";
  options.sample_rate_hz = 4000;
  try {
    LiveSynthesisAligner aligner(options, "settings.transcript");
    FAIL() << "a rate of 4000 Hz was accepted";
  } catch (const InputError& error) {
    EXPECT_THAT(error.what(), HasSubstr("4000 Hz is outside 8000-48000"));
  }
}

}  // namespace
}  // namespace lipsync::speech
