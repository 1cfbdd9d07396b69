// MBROLA .pho reader: durations in milliseconds accumulate from 0.
#include "format_test_support.hpp"

namespace lipsync {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing_support::fixture;
using testing_support::Interval;
using testing_support::parse_error;

TEST(Pho, AccumulatesDurationsFromZero) {
  const LabeledUtterance utterance = parse_utterance(fixture("speech.pho"), InputFormat::pho, "speech.pho");
  EXPECT_EQ(utterance.phone_set, "sampa");
  EXPECT_THAT(utterance.intervals, ElementsAre(Interval("_", 0, 150000, 3), Interval("s", 150000, 260000, 4),
                                               Interval("p", 260000, 322500, 5), Interval("i:", 322500, 440000, 7),
                                               Interval("tS", 440000, 570000, 8), Interval("_", 570000, 710000, 10)));
}

TEST(Pho, DurationsAreExactDecimalMilliseconds) {
  EXPECT_THAT(parse_utterance("a 0.0005\nb 1e2\nc 33.3333\n", InputFormat::pho, "x").intervals,
              ElementsAre(Interval("a", 0, 1, 1), Interval("b", 1, 100001, 2), Interval("c", 100001, 133334, 3)));
}

TEST(Pho, TrailingCommentsAndPercentSignsAreAccepted) {
  EXPECT_THAT(parse_utterance("a 10 50% 120 ; vowel\n", InputFormat::pho, "x").intervals,
              ElementsAre(Interval("a", 0, 10000, 1)));
}

TEST(Pho, ZeroDurationPassesThrough) {
  EXPECT_THAT(parse_utterance("a 0\nb 10\n", InputFormat::pho, "x").intervals,
              ElementsAre(Interval("a", 0, 0, 1), Interval("b", 0, 10000, 2)));
}

TEST(Pho, ErrorsNameLineFieldAndValue) {
  struct Case {
    std::string content;
    int line;
    std::vector<std::string> parts;
  };
  const Case cases[] = {
      {"_ 100\ns\n", 2, {"label duration_ms", "\"s\""}},
      {"_ 100\ns 1O0\n", 2, {"duration_ms", "not a number", "\"1O0\""}},
      {"_ 100\ns -20\n", 2, {"duration_ms", "negative", "\"-20\""}},
      {"_ 100\ns nan\n", 2, {"duration_ms", "not a finite number", "\"nan\""}},
      {"_ 100\ns 100000000\n", 2, {"duration_ms", "beyond 24 hours", "\"100000000\""}},
      {"_ 50000000\ns 50000000\n", 2, {"more than 24 hours"}},
      {"_ 100\ns 100 50\n", 2, {"pairs", "\"s 100 50\""}},
      {"_ 100\ns 100 x 120\n", 2, {"position", "\"x\""}},
      {"_ 100\ns 100 50 high\n", 2, {"pitch", "\"high\""}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.content);
    const InputError error = parse_error(c.content, InputFormat::pho);
    EXPECT_EQ(error.line(), c.line);
    for (const std::string& part : c.parts) EXPECT_THAT(error.message(), HasSubstr(part));
  }
}

}  // namespace
}  // namespace lipsync
