// Word marks as the TTS services return them (lipsync/word_marks.hpp): Amazon Polly's speech
// marks, an ElevenLabs alignment, Azure's word boundary events and audio.metadata messages, each
// as the service's documentation shows it; and the bad files a user may hand over, each refused
// naming the line or item and the field.
#include "lipsync/word_marks.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "lipsync/error.hpp"

namespace lipsync {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

auto Word(const std::string& text, std::int64_t start_us) {
  return ::testing::AllOf(::testing::Field(&TimedWord::text, text), ::testing::Field(&TimedWord::start_us, start_us));
}

std::string error_of(const std::string& text) {
  try {
    read_word_marks(text, "marks.json");
  } catch (const InputError& error) {
    return error.what();
  }
  return "no error";
}

TEST(WordMarks, PollySpeechMarksGiveTheWordMarksInMicroseconds) {
  // Polly's documented output for "Mary had a little lamb." with sentence, word and viseme marks.
  const std::string polly =
      "{\"time\":0,\"type\":\"sentence\",\"start\":0,\"end\":23,\"value\":\"Mary had a little lamb.\"}\n"
      "{\"time\":6,\"type\":\"word\",\"start\":0,\"end\":4,\"value\":\"Mary\"}\n"
      "{\"time\":6,\"type\":\"viseme\",\"value\":\"p\"}\n"
      "{\"time\":373,\"type\":\"word\",\"start\":5,\"end\":8,\"value\":\"had\"}\n"
      "{\"time\":604,\"type\":\"word\",\"start\":9,\"end\":10,\"value\":\"a\"}\n"
      "{\"time\":643,\"type\":\"word\",\"start\":11,\"end\":17,\"value\":\"little\"}\n"
      "{\"time\":882,\"type\":\"word\",\"start\":18,\"end\":22,\"value\":\"lamb\"}\n";
  EXPECT_THAT(read_word_marks(polly, "marks.json"),
              ElementsAre(Word("Mary", 6000), Word("had", 373000), Word("a", 604000), Word("little", 643000),
                          Word("lamb", 882000)));
}

TEST(WordMarks, AnElevenLabsAlignmentGivesEachRunOfCharactersItsFirstCharactersStart) {
  const std::string response =
      "{\"audio_base64\": \"UklGRg==\", \"alignment\": {"
      "\"characters\": [\"H\",\"i\",\" \",\"t\",\"h\",\"e\",\"r\",\"e\",\".\"],"
      "\"character_start_times_seconds\": [0.0, 0.116, 0.174, 0.209, 0.255, 0.29, 0.325, 0.372, 0.441],"
      "\"character_end_times_seconds\": [0.116, 0.174, 0.209, 0.255, 0.29, 0.325, 0.372, 0.441, 0.5]},"
      "\"normalized_alignment\": {\"characters\": [], \"character_start_times_seconds\": [],"
      "\"character_end_times_seconds\": []}}";
  EXPECT_THAT(read_word_marks(response, "marks.json"), ElementsAre(Word("Hi", 0), Word("there.", 209000)));
}

TEST(WordMarks, AzureWordBoundaryEventsAndMetadataMessagesGiveTicksAsMicroseconds) {
  // The Speech SDK's WordBoundary events as an application logs them (AudioOffset in 100 ns ticks),
  // a punctuation boundary skipped...
  const std::string events =
      "[{\"AudioOffset\": 500000, \"Duration\": \"00:00:00.2875000\", \"Text\": \"Hello\", \"TextOffset\": 0,"
      " \"WordLength\": 5, \"BoundaryType\": \"Word\"},"
      " {\"AudioOffset\": 3375000, \"Duration\": \"00:00:00.0500000\", \"Text\": \",\", \"BoundaryType\": "
      "\"Punctuation\"},"
      " {\"AudioOffset\": 3875000, \"Duration\": \"00:00:00.3000000\", \"Text\": \"world\", \"BoundaryType\": "
      "\"Word\"}]";
  EXPECT_THAT(read_word_marks(events, "marks.json"), ElementsAre(Word("Hello", 50000), Word("world", 387500)));
  // ...and the service's audio.metadata messages, one a line.
  const std::string metadata =
      "{\"Metadata\": [{\"Type\": \"WordBoundary\", \"Data\": {\"Offset\": 1000000, \"Duration\": 2500000, "
      "\"text\": {\"Text\": \"Good\", \"Length\": 4, \"BoundaryType\": \"WordBoundary\"}}}]}\n"
      "{\"Metadata\": [{\"Type\": \"SessionEnd\", \"Data\": {\"Offset\": 0}}]}\n"
      "{\"Metadata\": [{\"Type\": \"WordBoundary\", \"Data\": {\"Offset\": 4500000, \"Duration\": 3000000, "
      "\"text\": {\"Text\": \"morning\", \"Length\": 7, \"BoundaryType\": \"WordBoundary\"}}}]}\n";
  EXPECT_THAT(read_word_marks(metadata, "marks.json"), ElementsAre(Word("Good", 100000), Word("morning", 450000)));
}

TEST(WordMarks, BadFilesAreRefusedNamingTheLineOrItemAndTheField) {
  EXPECT_THAT(error_of(""), HasSubstr("marks.json: no word marks: the file is empty"));
  EXPECT_THAT(error_of("0.5 hello\n"), HasSubstr("marks.json:1: not JSON"));
  EXPECT_THAT(error_of("{\"time\":6,\"type\":\"word\",\"value\":\"a\"}\n{\"type\":\"word\",\"value\":\"b\",\"x\":1}\n"),
              HasSubstr("marks.json:2: a mark with none of the fields lipsync reads"));
  EXPECT_THAT(
      error_of("{\"time\":6,\"type\":\"word\",\"value\":\"a\"}\n{\"time\":\"7\",\"type\":\"word\",\"value\":\"b\"}"),
      HasSubstr("marks.json:2: \"time\" of a Polly word mark is \"7\", not a whole number"));
  EXPECT_THAT(error_of("{\"time\":6,\"type\":\"word\"}\n"),
              HasSubstr("marks.json:1: a Polly word mark without \"value\""));
  EXPECT_THAT(
      error_of("{\"time\":900,\"type\":\"word\",\"value\":\"a\"}\n{\"time\":800,\"type\":\"word\",\"value\":\"b\"}"),
      HasSubstr("marks.json:2: word 'b' starts at 800000 us, before the word before it ('a' at 900000 us)"));
  EXPECT_THAT(error_of("{\"time\":-5,\"type\":\"word\",\"value\":\"a\"}"),
              HasSubstr("\"time\" -5000 us is outside 0 to 24 h"));
  EXPECT_THAT(error_of("[{\"AudioOffset\": 1, \"Text\": \"a\"}, {\"AudioOffset\": 2}]"),
              HasSubstr("marks.json: item 2: an Azure word boundary without \"Text\""));
  EXPECT_THAT(error_of("{\"characters\": [\"a\"], \"character_start_times_seconds\": [0.1, 0.2]}"),
              HasSubstr("1 characters but 2 character_start_times_seconds"));
  EXPECT_THAT(error_of("{\"characters\": [\"a\", \"b\"], \"character_start_times_seconds\": [0.1, \"x\"]}"),
              HasSubstr("character 2: its start time is \"x\", not a number of seconds"));
  EXPECT_THAT(error_of("{\"time\":0,\"type\":\"sentence\",\"value\":\"Hi.\"}"),
              HasSubstr("no word marks in the file (no word with a time)"));
}

}  // namespace
}  // namespace lipsync
