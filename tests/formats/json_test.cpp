// lipsync utterance JSON reader: seconds or microseconds, errors by phoneme index.
#include "format_test_support.hpp"

namespace lipsync {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using testing_support::fixture;
using testing_support::Interval;
using testing_support::parse_error;

LabeledUtterance parse_json(std::string_view content) { return parse_utterance(content, InputFormat::json, "input"); }

TEST(Json, ReadsSecondsAndMicrosecondsWithPhonemeIndexAsLine) {
  const LabeledUtterance utterance = parse_utterance(fixture("utterance.json"), InputFormat::json, "utterance.json");
  EXPECT_EQ(utterance.source, "utterance.json");
  EXPECT_EQ(utterance.phone_set, "arpabet");
  EXPECT_THAT(utterance.intervals, ElementsAre(Interval("S", 50000, 160000, 1), Interval("P", 160000, 230000, 2),
                                               Interval("IY1", 230000, 350000, 3), Interval("CH", 350000, 480000, 4)));
}

TEST(Json, SecondsAreConvertedFromTheirDecimalText) {
  // 0.0000005 is below 0.5 µs as a double; as written it is exactly half and rounds up.
  const LabeledUtterance utterance = parse_json(R"({"phonemes": [
      {"label": "a", "start": 0.171, "end": 2},
      {"label": "b", "start": 1e-3, "end": 0.0000005},
      {"label": "c", "start": 0.2999995, "end": 12.3456784}]})");
  EXPECT_THAT(utterance.intervals, ElementsAre(Interval("a", 171000, 2000000, 1), Interval("b", 1000, 1, 2),
                                               Interval("c", 300000, 12345678, 3)));
}

TEST(Json, PhoneSetIsOptionalAndLabelsAreTrimmed) {
  const LabeledUtterance utterance = parse_json(R"({"phonemes": [{"label": "", "start": 0, "end": 0.1},
                                  {"label": " AA1 ", "start_us": 100000, "end_us": 100000}]})");
  EXPECT_EQ(utterance.phone_set, "");
  EXPECT_THAT(utterance.intervals, ElementsAre(Interval("", 0, 100000, 1), Interval("AA1", 100000, 100000, 2)));
}

TEST(Json, EmptyPhonemeListIsReadAsEmpty) { EXPECT_THAT(parse_json(R"({"phonemes": []})").intervals, IsEmpty()); }

TEST(Json, SyntaxErrorNamesLineAndColumn) {
  const InputError error = parse_error(
      "{\n  \"phonemes\": [\n    {\"label\": \"S\", \"start\": 0.1,, \"end\": 0.2}\n  ]\n}", InputFormat::json);
  EXPECT_EQ(error.line(), 3);
  EXPECT_THAT(error.message(), HasSubstr("invalid JSON at column 33"));
  EXPECT_THAT(error.message(), HasSubstr("syntax error"));
  EXPECT_THAT(error.message(), ::testing::Not(HasSubstr("json.exception")));
}

TEST(Json, TruncatedFileIsASyntaxError) {
  const InputError error = parse_error("{\"phonemes\": [\n", InputFormat::json);
  EXPECT_GE(error.line(), 1);
  EXPECT_THAT(error.message(), HasSubstr("invalid JSON"));
}

TEST(Json, DocumentErrorsHaveNoLine) {
  struct Case {
    std::string content;
    std::vector<std::string> parts;
  };
  const Case cases[] = {
      {R"([{"label": "a", "start": 0, "end": 1}])", {"JSON object", "array"}},
      {R"({"phones": []})", {"missing \"phonemes\""}},
      {R"({"phonemes": {"label": "a"}})", {"\"phonemes\" must be an array", "object"}},
      {R"({"phone_set": 3, "phonemes": []})", {"\"phone_set\" must be a string", "number"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.content);
    const InputError error = parse_error(c.content, InputFormat::json);
    EXPECT_EQ(error.line(), 0);
    for (const std::string& part : c.parts) EXPECT_THAT(error.message(), HasSubstr(part));
  }
}

TEST(Json, PhonemeErrorsNameIndexFieldAndValue) {
  const std::string good = R"({"label": "a", "start": 0, "end": 0.1}, )";
  struct Case {
    std::string phoneme;
    std::vector<std::string> parts;
  };
  const Case cases[] = {
      {R"("a")", {"phoneme 2", "expected an object", "string"}},
      {R"({"start": 0.1, "end": 0.2})", {"phoneme 2", "missing \"label\""}},
      {R"({"label": 7, "start": 0.1, "end": 0.2})", {"phoneme 2", "\"label\"", "found number 7"}},
      {R"({"label": "b", "end": 0.2})", {"phoneme 2", "missing \"start\"", "\"start_us\""}},
      {R"({"label": "b", "start": 0.1})", {"phoneme 2", "missing \"end\""}},
      {R"({"label": "b", "start": "0.1", "end": 0.2})",
       {"phoneme 2", "\"start\" must be a number of seconds", "found string \"0.1\""}},
      {R"({"label": "b", "start": -0.1, "end": 0.2})", {"phoneme 2", "\"start\"", "negative", "\"-0.1\""}},
      {R"({"label": "b", "start": 0.1, "end": -2})", {"phoneme 2", "\"end\"", "negative"}},
      {R"({"label": "b", "start": 0.1, "end": 90000.5})", {"phoneme 2", "\"end\"", "beyond 24 hours", "\"90000.5\""}},
      {R"({"label": "b", "start": 0.1, "end": 1e300})", {"phoneme 2", "\"end\"", "1e300"}},
      {R"({"label": "b", "start": 0.1, "start_us": 100000, "end": 0.2})",
       {"phoneme 2", "both \"start\" and \"start_us\""}},
      {R"({"label": "b", "start_us": 1.5, "end": 0.2})",
       {"phoneme 2", "\"start_us\"", "whole number of microseconds", "found number 1.5"}},
      {R"({"label": "b", "start_us": -3, "end": 0.2})", {"phoneme 2", "\"start_us\"", "negative"}},
      {R"({"label": "b", "start": 0, "end_us": 86400000001})",
       {"phoneme 2", "\"end_us\"", "beyond 24 hours", "86400000001"}},
      {R"({"label": "b", "start": 0, "end": null})", {"phoneme 2", "\"end\"", "null"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.phoneme);
    const InputError error = parse_error("{\"phonemes\": [" + good + c.phoneme + "]}", InputFormat::json);
    EXPECT_EQ(error.line(), 2);
    for (const std::string& part : c.parts) EXPECT_THAT(error.message(), HasSubstr(part));
  }
}

}  // namespace
}  // namespace lipsync
