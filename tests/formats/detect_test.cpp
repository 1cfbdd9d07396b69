// Format detection (content first, then extension), format names and the
// decoding every reader shares.
#include "format_test_support.hpp"

namespace lipsync {
namespace {

using ::testing::HasSubstr;
using ::testing::Optional;
using testing_support::fixture;
using testing_support::parse_error;

TEST(Detect, RecognisesEveryFixtureByContentAlone) {
  const std::pair<const char*, InputFormat> cases[] = {
      {"utterance.json", InputFormat::json},
      {"speech_long.TextGrid", InputFormat::textgrid},
      {"speech_short.TextGrid", InputFormat::textgrid},
      {"speech_chronological.TextGrid", InputFormat::textgrid},
      {"ipa_utf16be.TextGrid", InputFormat::textgrid},
      {"ipa_utf16le.TextGrid", InputFormat::textgrid},
      {"speech.PHN", InputFormat::timit},
      {"festival_speech_synchronization.lab", InputFormat::lab},
      {"arctic_style.lab", InputFormat::lab},
      {"speech.pho", InputFormat::pho},
      {"flite_speech_synchronization.psdur", InputFormat::flite},
      {"flite_two_sentences.psdur", InputFormat::flite},
  };
  for (const auto& [name, format] : cases) {
    SCOPED_TRACE(name);
    EXPECT_EQ(detect_input_format("input.txt", fixture(name)), format);
  }
}

TEST(Detect, RecognisesSmallInputsByContent) {
  EXPECT_EQ(detect_input_format("x", "  \n{\"phonemes\": []}"), InputFormat::json);
  EXPECT_EQ(detect_input_format("x", "0.1 100 pau\n0.25 100 m\n"), InputFormat::lab);
  EXPECT_EQ(detect_input_format("x", "pau:0.1 s:0.2\np:0.3\n"), InputFormat::flite);
  EXPECT_EQ(detect_input_format("x", "pau:0.1 s:0,2\n"), InputFormat::flite);  // reader says why
  EXPECT_EQ(detect_input_format("x", "; comment\n_ 100\na 80 50 120\n"), InputFormat::pho);
  EXPECT_EQ(detect_input_format("x", "0 1600 h#\n1600 3200 s\n"), InputFormat::timit);
}

TEST(Detect, ContentWinsOverExtension) {
  EXPECT_EQ(detect_input_format("speech.lab", fixture("utterance.json")), InputFormat::json);
  EXPECT_EQ(detect_input_format("speech.json", fixture("speech.PHN")), InputFormat::timit);
}

TEST(Detect, ExtensionDecidesWhenContentDoesNot) {
  const std::pair<const char*, InputFormat> cases[] = {
      {"a.json", InputFormat::json},         {"dir.x/a.TextGrid", InputFormat::textgrid},
      {"a.TEXTGRID", InputFormat::textgrid}, {"a.textgrid", InputFormat::textgrid},
      {"SA1.PHN", InputFormat::timit},       {"sa1.phn", InputFormat::timit},
      {"a.lab", InputFormat::lab},           {"a.pho", InputFormat::pho},
      {"a.psdur", InputFormat::flite},       {"C:\\data\\a.flite", InputFormat::flite},
  };
  for (const auto& [name, format] : cases) {
    SCOPED_TRACE(name);
    EXPECT_EQ(detect_input_format(name, ""), format);
    EXPECT_EQ(detect_input_format(name, "?? not any format ??\n"), format);
  }
}

TEST(Detect, UnknownInputIsAnErrorNamingTheFile) {
  for (const char* name : {"notes.txt", "noextension", "dir.lab/file"}) {
    SCOPED_TRACE(name);
    try {
      detect_input_format(name, "hello world\n");
      ADD_FAILURE() << "no error";
    } catch (const InputError& error) {
      EXPECT_EQ(error.source(), name);
      EXPECT_EQ(error.line(), 0);
      EXPECT_THAT(error.message(), HasSubstr("cannot tell the input format"));
      EXPECT_THAT(error.message(), HasSubstr("json, textgrid, timit, lab, pho or flite"));
    }
  }
}

TEST(Detect, HtkLabelsInALabFileAreRefused) {
  try {
    detect_input_format("speech.lab", "0 1100000 sil\n1100000 2300000 s\n");
    ADD_FAILURE() << "no error";
  } catch (const InputError& error) {
    EXPECT_EQ(error.source(), "speech.lab");
    EXPECT_THAT(error.message(), HasSubstr("HTK"));
    EXPECT_THAT(error.message(), HasSubstr("timit"));
  }
  EXPECT_EQ(detect_input_format("speech.PHN", "0 1100000 sil\n"), InputFormat::timit);
}

TEST(FormatNames, RoundTripAndIgnoreCase) {
  for (const InputFormat format : {InputFormat::json, InputFormat::textgrid, InputFormat::timit, InputFormat::lab,
                                   InputFormat::pho, InputFormat::flite}) {
    EXPECT_THAT(input_format_from_string(to_string(format)), Optional(format));
  }
  EXPECT_EQ(to_string(InputFormat::textgrid), "textgrid");
  EXPECT_THAT(input_format_from_string("TextGrid"), Optional(InputFormat::textgrid));
  EXPECT_EQ(input_format_from_string("praat"), std::nullopt);
  EXPECT_EQ(input_format_from_string(""), std::nullopt);
}

TEST(Encoding, InvalidUtf8IsAnErrorWithItsLine) {
  const InputError error = parse_error("pau:0.1\ns\xE9:0.2\n", InputFormat::flite);
  EXPECT_EQ(error.line(), 2);
  EXPECT_THAT(error.message(), HasSubstr("not valid UTF-8 (byte 0xE9)"));
}

TEST(Encoding, Utf16WithByteOrderMarkWorksForEveryFormat) {
  // "0 16 a\n" in UTF-16 LE and BE.
  const std::string le(
      "\xFF\xFE"
      "0\0 \0"
      "1\0"
      "6\0 \0a\0\n\0",
      16);
  const std::string be(
      "\xFE\xFF"
      "\0"
      "0\0 \0"
      "1\0"
      "6\0 \0a\0\n",
      16);
  for (const std::string& content : {le, be}) {
    const LabeledUtterance utterance = parse_utterance(content, InputFormat::timit, "x");
    ASSERT_EQ(utterance.intervals.size(), 1u);
    EXPECT_EQ(utterance.intervals[0].end_us, 1000);
  }
}

TEST(Encoding, BrokenUtf16IsAnError) {
  const InputError odd = parse_error(std::string("\xFF\xFE"
                                                 "a\0b",
                                                 5),
                                     InputFormat::flite);
  EXPECT_THAT(odd.message(), HasSubstr("odd number of bytes"));
  const InputError surrogate = parse_error(std::string("\xFF\xFE"
                                                       "a\0\n\0\x00\xD8"
                                                       "b\0",
                                                       10),
                                           InputFormat::flite);
  EXPECT_EQ(surrogate.line(), 2);
  EXPECT_THAT(surrogate.message(), HasSubstr("surrogate"));
}

}  // namespace
}  // namespace lipsync
