// How espeak-ng reads each script, with the real espeak-ng 1.51 of Debian 12: what lipsync gives it
// (Mandarin characters to the cmn voice's pinyin variant, U+02BC as an apostrophe) and what it says
// about the reading (a note naming words read by another language's rules, spelled out, or read
// without vowels; a refusal naming words whose reading would be the names of their characters).
// Through lipsync::speech, and through `lipsync say` and `lipsync voices` from the outside
// (docs/languages.md, "Scripts").
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "../support/lipsync_cli_test.hpp"
#include "lipsync/error.hpp"
#include "lipsync/speech/synthesizer.hpp"

namespace lipsync {
namespace {

using ::testing::AllOf;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;

speech::Synthesis speak(const std::string& text, const std::string& voice) {
  speech::SynthesisOptions options;
  options.voice = voice;
  return speech::synthesize(text, options);
}

/// The phonemes spoken, silences left out.
std::vector<std::string> sounds(const speech::Synthesis& synthesis) {
  std::vector<std::string> out;
  for (const LabeledInterval& interval : synthesis.phonemes.intervals) {
    if (!interval.label.empty()) out.push_back(interval.label);
  }
  return out;
}

/// The message of the InputError that speaking `text` in `voice` throws ("" if none).
std::string refusal(const std::string& text, const std::string& voice) {
  try {
    speak(text, voice);
  } catch (const InputError& error) {
    return error.message();
  }
  return "";
}

TEST(MandarinCharacters, AreSpokenAsMandarinByTheCmnVoice) {
  // espeak-ng 1.51's cmn voice alone reads its dictionary's pinyin ("wo3", "xiang3") by English rules:
  // "zaɪəŋ θɹiː" for 想, "wɒn" (one) for the tone digits.
  const speech::Synthesis speech = speak("我想喝一杯茶", "cmn");
  EXPECT_THAT(sounds(speech), ElementsAre("w", "o", "ɕ", "iɑ", "ŋ", "χ", "o-", "j", "i", "p", "ei", "ts.h", "ɑ"));
  EXPECT_THAT(speech.notes, IsEmpty());
  EXPECT_EQ(sounds(speech), sounds(speak("我想喝一杯茶", "cmn-latn-pinyin")));
  EXPECT_EQ(sounds(speech), sounds(speak("我想喝一杯茶", "zh-cmn")));
}

TEST(MandarinCharacters, KeepLatinWordsEnglishAndNameThem) {
  // The pinyin variant alone would read "like" and "tea" as pinyin; the cmn voice reads Latin as English.
  const speech::Synthesis speech = speak("我喜欢 I like tea", "cmn");  // "I" is read "ai", as pinyin
  const std::vector<std::string> spoken = sounds(speech);
  ASSERT_GE(spoken.size(), 6U);
  EXPECT_THAT(std::vector<std::string>(spoken.begin(), spoken.begin() + 6), ElementsAre("w", "o", "ɕ", "i", "χ", "ua"));
  EXPECT_THAT(spoken, ::testing::Contains("aɪ"));  // "I", "like" in English
  ASSERT_EQ(speech.notes.size(), 1U);
  EXPECT_THAT(speech.notes[0], AllOf(HasSubstr("'like'"), HasSubstr("'tea'"), HasSubstr("(en)")));
  // The intervals still tile the audio across the two runs.
  for (std::size_t i = 1; i < speech.phonemes.intervals.size(); ++i) {
    EXPECT_EQ(speech.phonemes.intervals[i].start_us, speech.phonemes.intervals[i - 1].end_us) << i;
  }
  EXPECT_EQ(speech.phonemes.intervals.back().end_us, speech.audio.duration_us());
}

TEST(JapaneseKanji, AreRefusedNamingTheWordAndWhatWorks) {
  // espeak-ng would say "Chinese letter" in English for each kanji.
  EXPECT_THAT(refusal("漢字です。", "ja"), AllOf(HasSubstr("'漢字です'"), HasSubstr("names of the characters"),
                                                 HasSubstr("kana"), HasSubstr("docs/languages.md")));
  EXPECT_THAT(speak("ありがとう", "ja").notes, IsEmpty());
}

TEST(Hebrew, PointedTextIsRefusedNamingTheWord) {
  // espeak-ng spells the word out and names each point in English ("Hebrew ... point").
  EXPECT_THAT(refusal("שָׁלוֹם", "he"), AllOf(HasSubstr("'שָׁלוֹם'"), HasSubstr("without points")));
}

TEST(Hebrew, UnpointedWordsReadWithoutVowelsAreNamed) {
  // שלום is in espeak-ng's dictionary (/ʃalom/); עולם is not and loses its vowels (/ʔvlm/).
  const speech::Synthesis speech = speak("שלום עולם", "he");
  ASSERT_EQ(speech.notes.size(), 1U);
  EXPECT_THAT(speech.notes[0],
              AllOf(HasSubstr("'עולם'"), Not(HasSubstr("'שלום'")), HasSubstr("/ʔvlm/"), HasSubstr("without vowels")));
}

TEST(UkrainianApostrophe, ModifierLetterApostropheIsReadAsTheApostrophe) {
  // Given as is, espeak-ng spells "мʼясо" out with U+02BC as the English word "ejective".
  const speech::Synthesis speech = speak("мʼясо і пʼять", "uk");
  EXPECT_EQ(sounds(speech), sounds(speak("м'ясо і п'ять", "uk")));
  EXPECT_THAT(sounds(speech), Not(::testing::Contains("dʒ")));
  EXPECT_THAT(speech.notes, IsEmpty());
}

TEST(LanguageSwitches, ALatinWordInRussianIsNamedAsReadInEnglish) {
  const speech::Synthesis speech = speak("hello мир", "ru");
  ASSERT_EQ(speech.notes.size(), 1U);
  EXPECT_THAT(speech.notes[0],
              AllOf(HasSubstr("'hello'"), Not(HasSubstr("мир")), HasSubstr("(en)"), HasSubstr("voice 'ru'")));
  EXPECT_THAT(speak("Привет, мир", "ru").notes, IsEmpty());
}

TEST(LanguageSwitches, ChineseCharactersInAnEnglishVoiceAreRefused) {
  EXPECT_THAT(refusal("日本 hello", "en-us"), AllOf(HasSubstr("'日本'"), HasSubstr("--voice cmn")));
}

TEST(UnknownVoices, AreRefusedNamingCloseMatchesNotTheEspeakProgram) {
  const std::optional<std::string> french = speech::unknown_voice_error("French");
  ASSERT_TRUE(french);
  EXPECT_THAT(*french, AllOf(HasSubstr("unknown voice 'French'"), HasSubstr("close matches: fr (French (France))"),
                             HasSubstr("'lipsync voices'"), Not(HasSubstr("espeak-ng --voices"))));
  EXPECT_THAT(speech::unknown_voice_error("Frnch").value_or(""), HasSubstr("fr (French (France))"));
  EXPECT_THAT(speech::unknown_voice_error("germn").value_or(""), HasSubstr("de (German)"));
  EXPECT_FALSE(speech::unknown_voice_error("fr"));
  EXPECT_FALSE(speech::unknown_voice_error("French (France)"));
  EXPECT_FALSE(speech::unknown_voice_error("de+m2"));
  EXPECT_THAT(refusal("bonjour", "French"), HasSubstr("fr (French (France))"));
}

class ReadingsCliTest : public testing::LipsyncCliTest {};

TEST_F(ReadingsCliTest, SayWarnsOnStderrNamingTheWordsAndStillWrites) {
  const testing::RunResult result = run({"say", "hello мир", "--voice", "ru", "-o", "t.json"});
  EXPECT_EQ(result.status, 0) << result.err;
  EXPECT_EQ(
      result.err,
      "lipsync: warning: espeak-ng read 'hello' by the rules of another language (en), not those of voice 'ru'\n");
  EXPECT_EQ(listing(), std::vector<std::string>{"t.json"});
}

TEST_F(ReadingsCliTest, SayRefusesKanjiWithExit1AndWritesNothing) {
  const testing::RunResult result = run({"say", "漢字", "--voice", "ja", "-o", "t.json"});
  EXPECT_EQ(result.status, 1);
  EXPECT_THAT(result.err,
              AllOf(HasSubstr("lipsync: error: espeak-ng: voice 'ja' cannot read '漢字'"), HasSubstr("kana")));
  EXPECT_THAT(listing(), IsEmpty());
}

TEST_F(ReadingsCliTest, SayRefusesAnUnknownVoiceNamingCloseOnes) {
  const testing::RunResult result = run({"say", "Bonjour", "--voice", "French", "-o", "t.json"});
  EXPECT_EQ(result.status, 1);
  EXPECT_THAT(result.err, AllOf(HasSubstr("close matches: fr (French (France))"), HasSubstr("'lipsync voices'"),
                                Not(HasSubstr("espeak-ng --voices"))));
}

TEST_F(ReadingsCliTest, VoicesListsTheNameVoiceTakesTheLanguagesAndTheName) {
  const testing::RunResult result = run({"voices"});
  EXPECT_EQ(result.status, 0) << result.err;
  EXPECT_THAT(result.out, AllOf(::testing::StartsWith("VOICE"), HasSubstr("LANGUAGES"), HasSubstr("NAME")));
  EXPECT_THAT(result.out, ::testing::ContainsRegex("\ncmn +cmn,zh-cmn,zh +Chinese \\(Mandarin, latin as English\\)\n"));
  EXPECT_THAT(result.out, ::testing::ContainsRegex("\nfr +fr-fr,fr +French \\(France\\)\n"));
  EXPECT_THAT(result.out, ::testing::ContainsRegex("\nen-us +en-us,en +English \\(America\\)\n"));
  std::size_t lines = 0;
  for (char c : result.out) lines += c == '\n' ? 1 : 0;
  EXPECT_EQ(lines, speech::list_voices().size() + 1);
  // Every name in the VOICE column is one --voice takes.
  for (const speech::Voice& voice : speech::list_voices()) {
    EXPECT_FALSE(speech::unknown_voice_error(speech::voice_option_name(voice))) << voice.identifier;
  }
}

}  // namespace
}  // namespace lipsync
