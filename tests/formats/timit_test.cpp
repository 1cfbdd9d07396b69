// TIMIT .PHN reader: sample numbers to microseconds at the given rate.
#include "format_test_support.hpp"

namespace lipsync {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing_support::fixture;
using testing_support::Interval;
using testing_support::parse_error;

TEST(Timit, ConvertsSamplesAtGivenRate) {
  const LabeledUtterance utterance = parse_utterance(fixture("speech.PHN"), InputFormat::timit, "speech.PHN");
  EXPECT_EQ(utterance.source, "speech.PHN");
  EXPECT_EQ(utterance.phone_set, "timit");
  EXPECT_THAT(utterance.intervals, ElementsAre(Interval("h#", 0, 150000, 1), Interval("s", 150000, 260000, 2),
                                               Interval("pcl", 260000, 300000, 3), Interval("p", 300000, 320000, 4),
                                               Interval("iy", 320000, 430000, 5), Interval("tcl", 430000, 480000, 6),
                                               Interval("ch", 480000, 560000, 7), Interval("h#", 560000, 700000, 8)));
}

TEST(Timit, SampleRateOptionScalesTimes) {
  ParseOptions options;
  options.timit_sample_rate_hz = 8000;
  const LabeledUtterance utterance = parse_utterance("0 800 h#\n800 2000 s\n", InputFormat::timit, "x.PHN", options);
  EXPECT_THAT(utterance.intervals, ElementsAre(Interval("h#", 0, 100000, 1), Interval("s", 100000, 250000, 2)));
}

TEST(Timit, RoundsToNearestMicrosecondExactly) {
  ParseOptions options;
  options.timit_sample_rate_hz = 44100;  // 1 sample = 22.6757... µs
  EXPECT_THAT(parse_utterance("0 1 a\n1 3 b\n", InputFormat::timit, "x", options).intervals,
              ElementsAre(Interval("a", 0, 23, 1), Interval("b", 23, 68, 2)));
  options.timit_sample_rate_hz = 3;  // 1 sample = 333333.33 µs, 2 samples = 666666.67 µs
  EXPECT_THAT(parse_utterance("1 2 a\n", InputFormat::timit, "x", options).intervals,
              ElementsAre(Interval("a", 333333, 666667, 1)));
  options.timit_sample_rate_hz = 2'000'000;  // 1 sample = 0.5 µs: half rounds up
  EXPECT_THAT(parse_utterance("1 3 a\n", InputFormat::timit, "x", options).intervals,
              ElementsAre(Interval("a", 1, 2, 1)));
  // 24 hours of 16 kHz samples, the largest time accepted, with no overflow on the way.
  EXPECT_THAT(parse_utterance("0 1382400000 a\n", InputFormat::timit, "x").intervals,
              ElementsAre(Interval("a", 0, 86'400'000'000, 1)));
}

TEST(Timit, AcceptsWindowsLineBreaksAndBlankLines) {
  EXPECT_THAT(parse_utterance("0 1600 h#\r\n\r\n1600 3200 s\r\n", InputFormat::timit, "x").intervals,
              ElementsAre(Interval("h#", 0, 100000, 1), Interval("s", 100000, 200000, 3)));
}

TEST(Timit, PassesZeroLengthAndReversedIntervalsToTheBuilder) {
  EXPECT_THAT(parse_utterance("100 100 a\n300 200 b\n", InputFormat::timit, "x").intervals,
              ElementsAre(Interval("a", 6250, 6250, 1), Interval("b", 18750, 12500, 2)));
}

TEST(Timit, RejectsNonPositiveSampleRate) {
  for (const int rate : {0, -16000}) {
    ParseOptions options;
    options.timit_sample_rate_hz = rate;
    const InputError error = parse_error("0 10 a\n", InputFormat::timit, options);
    EXPECT_EQ(error.line(), 0);
    EXPECT_THAT(error.message(), HasSubstr("sample rate"));
    EXPECT_THAT(error.message(), HasSubstr(std::to_string(rate)));
  }
}

TEST(Timit, MalformedLineShowsTheLineAndItsText) {
  const InputError error = parse_error("0 10 a\n10 20\n", InputFormat::timit);
  EXPECT_EQ(error.line(), 2);
  EXPECT_THAT(error.message(), HasSubstr("start_sample end_sample label"));
  EXPECT_THAT(error.message(), HasSubstr("\"10 20\""));
  const InputError extra = parse_error("0 10 a b\n", InputFormat::timit);
  EXPECT_EQ(extra.line(), 1);
  EXPECT_THAT(extra.message(), HasSubstr("\"0 10 a b\""));
}

TEST(Timit, LongOffendingTextIsTruncated) {
  const std::string line = "0 10 " + std::string(200, 'x') + " y";
  const InputError error = parse_error(line, InputFormat::timit);
  EXPECT_THAT(error.message(), HasSubstr("xxx...\""));
  EXPECT_LT(error.message().size(), 150u);
}

TEST(Timit, BadSampleNumbersNameFieldAndValue) {
  struct Case {
    std::string content;
    int line;
    std::string field;
    std::string value;
    std::string problem;
  };
  const Case cases[] = {
      {"0 10 a\n10 2O b\n", 2, "end_sample", "\"2O\"", "not a number"},
      {"-5 10 a\n", 1, "start_sample", "\"-5\"", "negative"},
      {"0 10 a\n10 15.5 b\n", 2, "end_sample", "\"15.5\"", "whole number"},
      {"0 nan a\n", 1, "end_sample", "\"nan\"", "not a number"},
      {"0 99999999999999999999999 a\n", 1, "end_sample", "\"99999999999999999999999\"", "beyond 24 hours"},
      {"0 1382400017 a\n", 1, "end_sample", "\"1382400017\"", "beyond 24 hours"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.content);
    const InputError error = parse_error(c.content, InputFormat::timit);
    EXPECT_EQ(error.line(), c.line);
    EXPECT_THAT(error.message(), HasSubstr(c.field));
    EXPECT_THAT(error.message(), HasSubstr(c.value));
    EXPECT_THAT(error.message(), HasSubstr(c.problem));
  }
}

}  // namespace
}  // namespace lipsync
