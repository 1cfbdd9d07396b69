#include "lipsync/time.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace lipsync {
namespace {

TEST(FormatSeconds, WritesSixExactDecimals) {
  EXPECT_EQ(format_seconds(0), "0.000000");
  EXPECT_EQ(format_seconds(1), "0.000001");
  EXPECT_EQ(format_seconds(33'333), "0.033333");
  EXPECT_EQ(format_seconds(3'600'000'001), "3600.000001");
  EXPECT_EQ(format_seconds(-5), "-0.000005");
}

TEST(ParseSeconds, DecimalTextIsExactToTheMicrosecond) {
  EXPECT_EQ(parse_seconds_to_us("0.171"), 171'000);
  EXPECT_EQ(parse_seconds_to_us("12"), 12'000'000);
  EXPECT_EQ(parse_seconds_to_us("1.000001"), 1'000'001);
  EXPECT_EQ(parse_seconds_to_us(".5"), 500'000);
  EXPECT_EQ(parse_seconds_to_us("1e-3"), 1'000);
  EXPECT_EQ(parse_seconds_to_us("2.5E2"), 250'000'000);
  EXPECT_EQ(parse_seconds_to_us("-0.25"), -250'000);
  EXPECT_EQ(parse_seconds_to_us("0.1234565"), 123'457);  // half rounds away from zero
  EXPECT_EQ(parse_seconds_to_us("0.0000004"), 0);
  EXPECT_EQ(parse_seconds_to_us("00000.000000000000000000001"), 0);
}

TEST(ParseSeconds, RejectsNonNumbersAndAbsurdTimes) {
  for (const char* bad : {"", "abc", "1.2.3", "1e", "nan", "inf", "0x10", "1,5", "- 1", "1e99999", "90000"}) {
    EXPECT_EQ(parse_seconds_to_us(bad), std::nullopt) << bad;
  }
  EXPECT_EQ(parse_seconds_to_us("86400"), kMaxTimeUs);
}

TEST(SecondsToUs, RoundsAndRejectsNonFinite) {
  EXPECT_EQ(seconds_to_us(0.0333333), 33'333);
  EXPECT_EQ(seconds_to_us(std::nan("")), std::nullopt);
  EXPECT_EQ(seconds_to_us(1e300), std::nullopt);
}

}  // namespace
}  // namespace lipsync
