// lipsyncd's stderr in --log-format json, as tests read it: one JSON object per
// line, each with an "event" (Animate.start, Subscribe.end, ...) or a message.
#pragma once

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

namespace lipsync::testing {

/// The lines of `log`, parsed; a line that is not a JSON object fails the test (and is left out).
inline std::vector<nlohmann::json> json_lines(const std::string& log) {
  std::vector<nlohmann::json> lines;
  std::istringstream in(log);
  for (std::string line; std::getline(in, line);) {
    auto parsed = nlohmann::json::parse(line, nullptr, false);
    if (!parsed.is_object()) {
      ADD_FAILURE() << "not a JSON object: " << line.substr(0, 200);
      continue;
    }
    lines.push_back(std::move(parsed));
  }
  return lines;
}

/// The first line whose "event" is `event`; nullptr if none.
inline const nlohmann::json* find_event(const std::vector<nlohmann::json>& lines, const std::string& event) {
  for (const auto& line : lines) {
    if (line.value("event", "") == event) return &line;
  }
  return nullptr;
}

}  // namespace lipsync::testing
