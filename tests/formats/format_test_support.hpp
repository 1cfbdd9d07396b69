// Helpers for the format reader tests: fixture loading, interval matchers that
// print the whole list on failure, and catching the InputError of a bad input.
#pragma once

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <ostream>
#include <sstream>
#include <string>
#include <string_view>

#include "lipsync/error.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync {

inline void PrintTo(const LabeledInterval& interval, std::ostream* out) {
  *out << "{\"" << interval.label << "\", " << interval.start_us << ", " << interval.end_us << ", line "
       << interval.line << "}";
}

namespace testing_support {

inline std::string fixture(std::string_view name) {
  const std::string path = std::string(LIPSYNC_TEST_DATA_DIR) + "/formats/" + std::string(name);
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    ADD_FAILURE() << "cannot open fixture " << path;
    return {};
  }
  std::ostringstream content;
  content << file.rdbuf();
  return content.str();
}

/// Interval with this label, start, end (µs) and source line.
inline auto Interval(std::string label, std::int64_t start_us, std::int64_t end_us, int line) {
  return ::testing::AllOf(::testing::Field("label", &LabeledInterval::label, label),
                          ::testing::Field("start_us", &LabeledInterval::start_us, start_us),
                          ::testing::Field("end_us", &LabeledInterval::end_us, end_us),
                          ::testing::Field("line", &LabeledInterval::line, line));
}

/// Interval with this label, start and end (µs), whatever its line.
inline auto Timing(std::string label, std::int64_t start_us, std::int64_t end_us) {
  return ::testing::AllOf(::testing::Field("label", &LabeledInterval::label, label),
                          ::testing::Field("start_us", &LabeledInterval::start_us, start_us),
                          ::testing::Field("end_us", &LabeledInterval::end_us, end_us));
}

/// The InputError that parsing `content` throws (a test failure if it throws none).
inline InputError parse_error(std::string_view content, InputFormat format, const ParseOptions& options = {}) {
  try {
    const LabeledUtterance utterance = parse_utterance(content, format, "input", options);
    ADD_FAILURE() << "expected an InputError, got " << utterance.intervals.size() << " intervals";
  } catch (const InputError& error) {
    EXPECT_EQ(error.source(), "input");
    return error;
  }
  return InputError("", -1, "no error");
}

}  // namespace testing_support
}  // namespace lipsync
