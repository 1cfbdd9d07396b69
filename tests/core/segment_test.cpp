#include "lipsync/segment.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "lipsync/error.hpp"
#include "lipsync/phone_set.hpp"
#include "test_model.hpp"

namespace lipsync {
namespace {

using ::testing::HasSubstr;
using testing::test_model;

const PhoneSet& test_phone_set() {
  static const PhoneSet set = PhoneSet::from_json(R"({
    "format": "lipsync-phone-set", "version": 1, "name": "test-set", "case_sensitive": false,
    "ignore_characters": "012",
    "phones": {"AA": "aa", "IY": "iy", "S": "s", "T": "t", "P": "p", "PCL": "pcl", "M": "m", "SIL": "sil"}
  })",
                                                  "test phone set", test_model());
  return set;
}

struct Named {
  std::string name;
  std::int64_t start_us;
  std::int64_t end_us;
  bool operator==(const Named&) const = default;
};

void PrintTo(const Named& n, std::ostream* os) { *os << n.name << " [" << n.start_us << ", " << n.end_us << ")"; }

std::vector<Named> names(const std::vector<Segment>& segments) {
  std::vector<Named> out;
  for (const auto& s : segments) out.push_back({test_model().phoneme(s.phoneme).name, s.start_us, s.end_us});
  return out;
}

std::vector<Segment> build(std::vector<LabeledInterval> intervals, SegmentOptions options = {}) {
  return build_segments({"input.lab", "", std::move(intervals)}, test_model(), test_phone_set(), options);
}

std::string error_of(std::vector<LabeledInterval> intervals) {
  try {
    build(std::move(intervals));
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(SegmentBuilder, MapsLabelsThroughThePhoneSet) {
  EXPECT_THAT(names(build({{"AA1", 0, 100, 1}, {"s", 100, 200, 2}, {"", 200, 300, 3}})),
              ::testing::ElementsAre(Named{"aa", 0, 100}, Named{"s", 100, 200}, Named{"sil", 200, 300}));
}

TEST(SegmentBuilder, GapsAndALeadingGapBecomeSilence) {
  EXPECT_THAT(
      names(build({{"AA", 50, 100, 1}, {"S", 150, 200, 2}})),
      ::testing::ElementsAre(Named{"sil", 0, 50}, Named{"aa", 50, 100}, Named{"sil", 100, 150}, Named{"s", 150, 200}));
}

TEST(SegmentBuilder, SplitsAStopWithoutClosureIntoClosureAndRelease) {
  EXPECT_THAT(names(build({{"AA", 0, 100, 1}, {"P", 100, 200, 2}}, {.closure_fraction = 0.6})),
              ::testing::ElementsAre(Named{"aa", 0, 100}, Named{"pcl", 100, 160}, Named{"p", 160, 200}));
  EXPECT_THAT(names(build({{"P", 0, 1000, 1}}, {.closure_fraction = 0.25})),
              ::testing::ElementsAre(Named{"pcl", 0, 250}, Named{"p", 250, 1000}));
}

TEST(SegmentBuilder, KeepsAStopThatFollowsItsOwnClosure) {
  EXPECT_THAT(names(build({{"PCL", 0, 100, 1}, {"P", 100, 130, 2}})),
              ::testing::ElementsAre(Named{"pcl", 0, 100}, Named{"p", 100, 130}));
}

TEST(SegmentBuilder, SplitKeepsAtLeastOneMicrosecondOnEachSide) {
  EXPECT_THAT(names(build({{"P", 0, 2, 1}}, {.closure_fraction = 0.99})),
              ::testing::ElementsAre(Named{"pcl", 0, 1}, Named{"p", 1, 2}));
}

TEST(SegmentBuilder, RejectsUnknownLabelsNamingThePhoneSetAndLine) {
  const std::string message = error_of({{"AA", 0, 100, 1}, {"XX", 100, 200, 7}});
  EXPECT_THAT(message, HasSubstr("input.lab:7"));
  EXPECT_THAT(message, HasSubstr("'XX'"));
  EXPECT_THAT(message, HasSubstr("test-set"));
}

TEST(SegmentBuilder, RejectsOverlapsReversedAndZeroDurations) {
  EXPECT_THAT(error_of({{"AA", 0, 100, 1}, {"S", 90, 200, 2}}),
              ::testing::AllOf(HasSubstr("input.lab:2"), HasSubstr("0.000090 s"), HasSubstr("overlap")));
  EXPECT_THAT(error_of({{"AA", 0, 100, 1}, {"S", 300, 200, 2}}),
              ::testing::AllOf(HasSubstr("input.lab:2"), HasSubstr("before it starts")));
  EXPECT_THAT(error_of({{"AA", 100, 100, 4}}), ::testing::AllOf(HasSubstr("input.lab:4"), HasSubstr("zero duration")));
  EXPECT_THAT(error_of({{"AA", -5, 100, 1}}), HasSubstr("negative"));
  EXPECT_THAT(error_of({{"AA", 0, 100LL * 3600 * 1'000'000, 1}}), HasSubstr("24 hours"));
  EXPECT_THAT(error_of({}), HasSubstr("no phonemes"));
}

TEST(SegmentBuilder, LeavesNoTraceOfARejectedInterval) {
  SegmentBuilder builder(test_model(), test_phone_set(), "stream");
  std::vector<Segment> segments;
  builder.push({"AA", 0, 100, 1}, segments);
  EXPECT_THROW(builder.push({"XX", 150, 200, 2}, segments), InputError);
  EXPECT_EQ(segments.size(), 1U);
  builder.push({"S", 100, 200, 3}, segments);
  EXPECT_THAT(names(segments), ::testing::ElementsAre(Named{"aa", 0, 100}, Named{"s", 100, 200}));
}

TEST(SegmentBuilder, RejectsClosureFractionsOutsideZeroToOne) {
  EXPECT_THROW(SegmentBuilder(test_model(), test_phone_set(), "x", {.closure_fraction = 0.0}), std::invalid_argument);
  EXPECT_THROW(SegmentBuilder(test_model(), test_phone_set(), "x", {.closure_fraction = 1.0}), std::invalid_argument);
}

}  // namespace
}  // namespace lipsync
