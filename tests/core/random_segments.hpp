// Random contiguous segment sequences over a model's whole inventory, with a
// fixed seed: durations from 1 µs to 400 ms, skewed short, so that every class
// (closures, releases, very short segments) shows up in property tests.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "lipsync/model.hpp"
#include "lipsync/segment.hpp"

namespace lipsync::testing {

inline std::vector<Segment> random_segments(const ArticulationModel& model, std::size_t count, std::uint64_t seed) {
  std::mt19937_64 random(seed);
  std::vector<Segment> segments;
  std::int64_t time_us = 0;
  for (std::size_t i = 0; i < count; ++i) {
    const int phoneme = static_cast<int>(random() % model.phonemes().size());
    const std::uint64_t roll = random() % 100;
    std::int64_t duration_us = 0;
    if (roll < 5)
      duration_us = 1 + static_cast<std::int64_t>(random() % 1000);  // ≤ 1 ms
    else if (roll < 20)
      duration_us = 1000 + static_cast<std::int64_t>(random() % 29000);  // shorter than a frame
    else
      duration_us = 30000 + static_cast<std::int64_t>(random() % 370000);
    segments.push_back({phoneme, model.phoneme(phoneme).phoneme_class, time_us, time_us + duration_us, 0});
    time_us += duration_us;
  }
  return segments;
}

}  // namespace lipsync::testing
