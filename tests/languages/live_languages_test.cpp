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
// - A transcript of 16 KiB is spoken by espeak-ng a few sentences ahead of the speech, not whole
//   before the first piece; a stream of three minutes drops what it has heard and hears its last
//   sentence as its first.
// - A minute of silence after the speech keeps the window (the audio the aligner holds) as short as
//   the commit delay; audio with no words to hear is silence, and a note says so.
// - Bad input: an unknown voice, a sample rate outside 8000-48000.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "../support/recorded_languages.hpp"
#include "lipsync/error.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/live_synthesis_aligner.hpp"

namespace lipsync::speech {
namespace {

using ::testing::HasSubstr;

using Item = testing::RecordedLanguage;

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
