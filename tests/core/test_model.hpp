// A small hand-written model for engine tests whose expected numbers must not
// move when the default model is retuned: three channels, a handful of phonemes.
#pragma once

#include <string>
#include <vector>

#include "lipsync/model.hpp"
#include "lipsync/segment.hpp"

namespace lipsync::testing {

inline constexpr const char* kTestModelJson = R"({
  "format": "lipsync-articulation-model", "version": 1, "name": "test",
  "channels": [
    {"name": "lips", "kind": "muscle", "min": 0, "max": 1, "rest": 0},
    {"name": "jaw", "kind": "jaw", "min": 0, "max": 1, "rest": 0},
    {"name": "tongue", "kind": "tongue", "min": -1, "max": 1, "rest": 0}
  ],
  "dominance_defaults": {"alpha": 1, "theta_minus_per_s": 20, "theta_plus_per_s": 20, "c": 1, "t_off_ms": 0},
  "phonemes": {
    "sil": {"class": "silence", "dominance": {"alpha": 0.5}},
    "low": {"class": "vowel", "targets": {"lips": 0.1, "jaw": 0.1, "tongue": -0.5}},
    "high": {"class": "vowel", "targets": {"lips": 0.9, "jaw": 0.9, "tongue": 0.5}},
    "aa": {"class": "vowel", "targets": {"lips": 0.2, "jaw": 0.8, "tongue": -0.6}},
    "iy": {"class": "vowel", "targets": {"lips": 0.3, "jaw": 0.2, "tongue": 0.7}},
    "s": {"class": "consonant", "targets": {"lips": 0.1, "jaw": 0.1, "tongue": 0.9}},
    "t": {"class": "consonant", "targets": {"lips": 0.0, "jaw": 0.15, "tongue": 1.0}},
    "ch": {"class": "consonant", "targets": {"lips": 0.5, "jaw": 0.1, "tongue": 0.8}},
    "pcl": {"class": "closure", "targets": {"lips": 1.0, "jaw": 0.05},
            "channel_dominance": {"lips": {"alpha": 8}}},
    "m": {"class": "closure", "targets": {"lips": 0.9, "jaw": 0.05},
          "channel_dominance": {"lips": {"alpha": 8}}},
    "p": {"class": "release", "closure": "pcl", "targets": {"lips": 0.3, "jaw": 0.2}},
    "sharp": {"class": "vowel", "targets": {"lips": 1.0}, "dominance": {"c": 2, "theta_plus_per_s": 400, "theta_minus_per_s": 300, "t_off_ms": 10}}
  },
  "arkit": {"jawOpen": {"weights": {"jaw": 1.0}}}
})";

inline const ArticulationModel& test_model() {
  static const ArticulationModel model = ArticulationModel::from_json(kTestModelJson, "test model");
  return model;
}

/// Segments from (phoneme name, start s, end s) triples of the test model.
struct TimedName {
  const char* name;
  double start_s;
  double end_s;
};

inline std::vector<Segment> make_segments(const ArticulationModel& model, const std::vector<TimedName>& items) {
  std::vector<Segment> segments;
  for (const auto& item : items) {
    const int index = *model.find_phoneme(item.name);
    segments.push_back({index, model.phoneme(index).phoneme_class, static_cast<std::int64_t>(item.start_s * 1e6 + 0.5),
                        static_cast<std::int64_t>(item.end_s * 1e6 + 0.5), 0});
  }
  return segments;
}

}  // namespace lipsync::testing
