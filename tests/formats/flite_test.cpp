// flite -psdur reader: "label:end_seconds" tokens, start = previous end.
#include <cstdio>
#include <filesystem>

#include "format_test_support.hpp"

namespace lipsync {
namespace {

using ::testing::Each;
using ::testing::ElementsAre;
using ::testing::ElementsAreArray;
using ::testing::Field;
using ::testing::HasSubstr;
using testing_support::fixture;
using testing_support::Interval;
using testing_support::parse_error;

std::vector<std::string> labels_of(const LabeledUtterance& utterance) {
  std::vector<std::string> labels;
  for (const LabeledInterval& interval : utterance.intervals) labels.push_back(interval.label);
  return labels;
}

TEST(Flite, ReadsFliteOutput) {
  // Real output of: flite -voice slt -psdur -t "speech synchronization" -o none
  const LabeledUtterance utterance =
      parse_utterance(fixture("flite_speech_synchronization.psdur"), InputFormat::flite, "speech.psdur");
  EXPECT_EQ(utterance.phone_set, "radio");
  EXPECT_THAT(utterance.intervals, ElementsAre(Interval("pau", 0, 171000, 1), Interval("s", 171000, 287000, 1),
                                               Interval("p", 287000, 352000, 1), Interval("iy", 352000, 447000, 1),
                                               Interval("ch", 447000, 599000, 1), Interval("s", 599000, 701000, 1),
                                               Interval("ih", 701000, 781000, 1), Interval("ng", 781000, 873000, 1),
                                               Interval("k", 873000, 935000, 1), Interval("r", 935000, 977000, 1),
                                               Interval("ax", 977000, 1014000, 1), Interval("n", 1014000, 1060000, 1),
                                               Interval("ax", 1060000, 1122000, 1), Interval("z", 1122000, 1206000, 1),
                                               Interval("ey", 1206000, 1381000, 1), Interval("sh", 1381000, 1515000, 1),
                                               Interval("ax", 1515000, 1620000, 1), Interval("n", 1620000, 1775000, 1),
                                               Interval("pau", 1775000, 1960000, 1)));
}

TEST(Flite, ReadsTwoSentenceOutput) {
  const LabeledUtterance utterance =
      parse_utterance(fixture("flite_two_sentences.psdur"), InputFormat::flite, "two.psdur");
  ASSERT_EQ(utterance.intervals.size(), 21u);
  EXPECT_THAT(utterance.intervals[9], Interval("pau", 1024000, 1150000, 1));
  EXPECT_THAT(utterance.intervals.back(), Interval("pau", 2105000, 2356000, 1));
}

TEST(Flite, TokensMaySpanLinesAndKeepTheirLine) {
  EXPECT_THAT(
      parse_utterance("pau:0.1 s:0.2\n\n  p:0.35\n", InputFormat::flite, "x").intervals,
      ElementsAre(Interval("pau", 0, 100000, 1), Interval("s", 100000, 200000, 1), Interval("p", 200000, 350000, 3)));
}

TEST(Flite, ErrorsNameLineTokenAndValue) {
  struct Case {
    std::string content;
    int line;
    std::vector<std::string> parts;
  };
  const Case cases[] = {
      {"pau:0.1\ns0.2\n", 2, {"label:end_seconds", "\"s0.2\""}},
      {"pau:0.1 :0.2\n", 1, {"missing label", "\":0.2\""}},
      {"pau:0.1\n\ns:0.2x\n", 3, {"end time of \"s\"", "not a number", "\"0.2x\""}},
      {"pau:-0.1\n", 1, {"end time of \"pau\"", "negative", "\"-0.1\""}},
      {"pau:NaN\n", 1, {"not a finite number", "\"NaN\""}},
      {"pau:1e6\n", 1, {"beyond 24 hours", "\"1e6\""}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.content);
    const InputError error = parse_error(c.content, InputFormat::flite);
    EXPECT_EQ(error.line(), c.line);
    for (const std::string& part : c.parts) EXPECT_THAT(error.message(), HasSubstr(part));
  }
}

// Runs the installed flite, so that a change in its output layout shows up here.
TEST(Flite, LiveFliteOutputParses) {
  const char* const flite = "/usr/bin/flite";
  ASSERT_TRUE(std::filesystem::exists(flite))
      << flite << " is missing: install the Debian package flite (apt-get install flite)";
  FILE* pipe = popen("/usr/bin/flite -voice slt -psdur -t 'speech synchronization' -o none", "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[4096];
  while (const std::size_t read = std::fread(buffer, 1, sizeof buffer, pipe)) {
    output.append(buffer, read);
  }
  ASSERT_EQ(pclose(pipe), 0) << "flite failed; its output: " << output;

  EXPECT_EQ(detect_input_format("-", output), InputFormat::flite) << output;
  const LabeledUtterance live = parse_utterance(output, InputFormat::flite, "flite");
  const LabeledUtterance committed =
      parse_utterance(fixture("flite_speech_synchronization.psdur"), InputFormat::flite, "speech.psdur");
  EXPECT_THAT(labels_of(live), ElementsAreArray(labels_of(committed)));
  ASSERT_FALSE(live.intervals.empty());
  EXPECT_EQ(live.intervals.front().start_us, 0);
  for (std::size_t i = 1; i < live.intervals.size(); ++i) {
    EXPECT_EQ(live.intervals[i].start_us, live.intervals[i - 1].end_us) << "interval " << i;
    EXPECT_GT(live.intervals[i].end_us, live.intervals[i].start_us) << "interval " << i;
  }
  EXPECT_THAT(live.intervals, Each(Field(&LabeledInterval::line, 1)));
}

}  // namespace
}  // namespace lipsync
