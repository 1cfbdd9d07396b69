#include "lipsync/synthetic.hpp"

#include <array>
#include <string_view>

namespace lipsync {
namespace {

/// SplitMix64: small, fast, and the same everywhere.
class Random {
 public:
  explicit Random(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1).
  double unit() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  /// Uniform integer in [low, high].
  std::int64_t between(std::int64_t low, std::int64_t high) {
    return low + static_cast<std::int64_t>(next() % static_cast<std::uint64_t>(high - low + 1));
  }
  template <typename T, std::size_t N>
  const T& pick(const std::array<T, N>& items) {
    return items[next() % N];
  }

 private:
  std::uint64_t state_;
};

struct PhoneClass {
  std::array<std::string_view, 9> labels;
  std::size_t count;
  std::int64_t min_ms;
  std::int64_t max_ms;
};

constexpr std::array<std::string_view, 15> kVowels = {"AA", "AE", "AH", "AO", "AW", "AY", "EH", "ER",
                                                      "EY", "IH", "IY", "OW", "OY", "UH", "UW"};
constexpr PhoneClass kStops{{"P", "B", "T", "D", "K", "G", "CH", "JH"}, 8, 40, 110};
constexpr PhoneClass kFricatives{{"F", "V", "TH", "DH", "S", "Z", "SH", "ZH", "HH"}, 9, 60, 160};
constexpr PhoneClass kNasals{{"M", "N", "NG"}, 3, 40, 100};
constexpr PhoneClass kApproximants{{"L", "R", "W", "Y"}, 4, 35, 90};
constexpr std::array<const PhoneClass*, 4> kConsonantClasses = {&kStops, &kFricatives, &kNasals, &kApproximants};

}  // namespace

std::vector<LabeledInterval> synthesize_utterance(const SyntheticOptions& options) {
  Random random(options.seed);
  std::vector<LabeledInterval> intervals;
  intervals.reserve(options.phonemes);
  std::int64_t time_us = 0;
  bool vowel_next = random.unit() < 0.5;
  for (std::size_t i = 0; intervals.size() < options.phonemes; ++i) {
    std::string label;
    std::int64_t duration_ms = 0;
    bool pause = i > 0 && random.unit() < options.pause_share;
    if (pause) {
      label = "SIL";
      duration_ms = random.unit() < options.long_pause_share ? random.between(1000, 3000) : random.between(100, 500);
    } else if (vowel_next) {
      label = std::string(random.pick(kVowels)) + static_cast<char>('0' + random.between(0, 2));
      // Sum of two uniforms: more mid-length vowels than extremes.
      duration_ms = (random.between(50, 220) + random.between(50, 220)) / 2;
      vowel_next = random.unit() < 0.15;  // occasional vowel hiatus
    } else {
      const PhoneClass& cls = *random.pick(kConsonantClasses);
      label = std::string(cls.labels[random.next() % cls.count]);
      duration_ms =
          random.unit() < options.short_share ? random.between(5, 25) : random.between(cls.min_ms, cls.max_ms);
      vowel_next = random.unit() < 0.7;  // consonant clusters are common
    }
    const std::int64_t duration_us = duration_ms * 1000 + random.between(0, 999);
    if (!(pause && options.leave_gaps)) {
      intervals.push_back({label, time_us, time_us + duration_us, static_cast<int>(intervals.size() + 1)});
    }
    time_us += duration_us;
  }
  return intervals;
}

}  // namespace lipsync
