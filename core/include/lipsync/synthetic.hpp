// Synthetic utterances for property tests, benchmarks and load tests: ARPAbet
// labels with durations drawn from per-class ranges typical of read speech
// (vowels 50–220 ms, stops 40–110 ms, ...), a share of very short phonemes
// (5–25 ms, shorter than any frame interval) and pauses, some of them long.
// Deterministic for a seed on every platform (own generator, own
// distributions: the standard library's distributions differ between vendors).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "lipsync/utterance.hpp"

namespace lipsync {

struct SyntheticOptions {
  std::size_t phonemes = 100;  ///< intervals to generate (pauses included)
  std::uint64_t seed = 1;
  double short_share = 0.05;      ///< share of consonants given 5–25 ms
  double pause_share = 0.06;      ///< share of intervals that are pauses ("SIL")
  double long_pause_share = 0.1;  ///< share of pauses that last 1–3 s
  bool leave_gaps = false;        ///< omit pause labels, leaving gaps (which become silence)
};

/// Contiguous intervals from time 0 with ARPAbet labels (vowels with stress digits).
std::vector<LabeledInterval> synthesize_utterance(const SyntheticOptions& options);

}  // namespace lipsync
