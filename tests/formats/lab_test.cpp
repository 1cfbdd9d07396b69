// Festival / CMU ARCTIC .lab reader: end times after a "#" header line.
#include "format_test_support.hpp"

namespace lipsync {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing_support::fixture;
using testing_support::Interval;
using testing_support::parse_error;

TEST(Lab, ReadsFestivalSegments) {
  // Real output of: festival -b '(voice_kal_diphone)'
  //   '(set! u (SynthText "speech synchronization"))' '(utt.save.segs u "-")'
  const LabeledUtterance utterance =
      parse_utterance(fixture("festival_speech_synchronization.lab"), InputFormat::lab, "festival.lab");
  EXPECT_EQ(utterance.phone_set, "radio");
  EXPECT_THAT(
      utterance.intervals,
      ElementsAre(Interval("pau", 0, 220000, 2), Interval("s", 220000, 345500, 3), Interval("p", 345500, 431700, 4),
                  Interval("iy", 431700, 530800, 5), Interval("ch", 530800, 659000, 6),
                  Interval("s", 659000, 784500, 7), Interval("ih", 784500, 831800, 8),
                  Interval("ng", 831800, 894900, 9), Interval("k", 894900, 988000, 10),
                  Interval("r", 988000, 1020200, 11), Interval("ax", 1020200, 1047000, 12),
                  Interval("n", 1047000, 1102000, 13), Interval("ax", 1102000, 1158600, 14),
                  Interval("z", 1158600, 1244800, 15), Interval("ey", 1244800, 1355600, 16),
                  Interval("sh", 1355600, 1496100, 17), Interval("ax", 1496100, 1546700, 18),
                  Interval("n", 1546700, 1623700, 19), Interval("pau", 1623700, 1843700, 20)));
}

TEST(Lab, ReadsSecondFestivalUtterance) {
  const LabeledUtterance utterance = parse_utterance(fixture("festival_mama.lab"), InputFormat::lab, "mama.lab");
  ASSERT_EQ(utterance.intervals.size(), 15u);
  EXPECT_THAT(utterance.intervals.front(), Interval("pau", 0, 220000, 2));
  EXPECT_THAT(utterance.intervals[1], Interval("m", 220000, 288800, 3));
  EXPECT_THAT(utterance.intervals.back(), Interval("pau", 1288800, 1737600, 16));
}

TEST(Lab, SkipsHeaderLinesUpToTheHashLine) {
  const LabeledUtterance utterance = parse_utterance(fixture("arctic_style.lab"), InputFormat::lab, "arctic.lab");
  EXPECT_THAT(utterance.intervals, ElementsAre(Interval("pau", 0, 150000, 4), Interval("s", 150000, 260000, 5),
                                               Interval("p", 260000, 320000, 6), Interval("iy", 320000, 430000, 7),
                                               Interval("ch", 430000, 560000, 8), Interval("pau", 560000, 700000, 9)));
}

TEST(Lab, ReadsFileWithoutHeader) {
  EXPECT_THAT(parse_utterance("0.1 100 pau\n\n0.25 100 m\n", InputFormat::lab, "x").intervals,
              ElementsAre(Interval("pau", 0, 100000, 1), Interval("m", 100000, 250000, 3)));
}

TEST(Lab, ColourMayBeAnyInteger) {
  EXPECT_THAT(parse_utterance("#\n0.1 -3 pau\n0.2 +26 m\n", InputFormat::lab, "x").intervals,
              ElementsAre(Interval("pau", 0, 100000, 2), Interval("m", 100000, 200000, 3)));
}

TEST(Lab, ErrorsNameLineFieldAndValue) {
  struct Case {
    std::string content;
    int line;
    std::vector<std::string> parts;
  };
  const Case cases[] = {
      {"#\n0.1 100 pau\n0.2 100\n", 3, {"end_time colour label", "\"0.2 100\""}},
      {"#\n0.1 100 pau\n0.2 100 m extra\n", 3, {"\"0.2 100 m extra\""}},
      {"#\n0.1 100 pau\n0,2 100 m\n", 3, {"end_time", "not a number", "\"0,2\""}},
      {"#\n-0.1 100 pau\n", 2, {"end_time", "negative", "\"-0.1\""}},
      {"#\ninf 100 pau\n", 2, {"end_time", "not a finite number", "\"inf\""}},
      {"#\n90000 100 pau\n", 2, {"end_time", "beyond 24 hours", "\"90000\""}},
      {"#\n0.1 1.5 pau\n", 2, {"colour", "not an integer", "\"1.5\""}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.content);
    const InputError error = parse_error(c.content, InputFormat::lab);
    EXPECT_EQ(error.line(), c.line);
    for (const std::string& part : c.parts) EXPECT_THAT(error.message(), HasSubstr(part));
  }
}

}  // namespace
}  // namespace lipsync
