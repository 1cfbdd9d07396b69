// Scoring an alignment against known phoneme boundaries, for the accuracy tool
// (tests/bench/alignment_accuracy.cpp) and the alignment tests.
//
// The reference (a synthesiser's own phonemes, in its phone set) and the
// alignment (ARPAbet) are first mapped to the model's phonemes through the
// built-in phone sets, adjacent silences merged, and the two sequences are
// matched by edit distance (substitution, insertion and deletion cost 1; equal
// phonemes cost 0), so a word the dictionary pronounces differently from the
// synthesiser costs only its own phones. For every phoneme matched to an equal
// one, the boundary error is the distance between the two start times (the
// utterance's first phoneme, starting at 0 in both, is left out). A bilabial
// closure (/p b m/) of the reference is "found" when it is matched to the same
// phoneme starting within 20 ms. Independently of the matching, a reference
// bilabial is "shown closed" when the alignment has a /p b m/ at the middle of
// the reference closure (what a viewer sees there, whatever the phone names), and any
// other reference phoneme (silence aside) shows a "false closure" when the alignment
// has a /p b m/ at its middle.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <string>
#include <vector>

#include "../support/harvard_sentences.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync::testing {

/// The first ten Harvard sentences: the utterances the alignment accuracy is measured on.
inline std::span<const char* const> accuracy_sentences() { return std::span(kHarvardSentences).first(10); }

struct BoundaryScore {
  std::vector<double> errors_ms;         ///< one per matched boundary
  std::vector<double> signed_errors_ms;  ///< aligned minus reference start, one per matched boundary
  int reference_phonemes = 0;            ///< after merging silences
  int matched_phonemes = 0;              ///< matched to an equal phoneme
  int bilabials = 0;                     ///< /p b m/ in the reference
  int bilabials_within_20ms = 0;
  std::vector<double> bilabial_errors_ms;  ///< start error of each matched reference /p b m/
  int bilabials_closed_at_middle = 0;      ///< reference /p b m/ whose middle the alignment labels /p b m/
  int other_phonemes = 0;                  ///< reference phonemes neither /p b m/ nor silence
  int false_closures = 0;                  ///< of those, the ones whose middle the alignment labels /p b m/
};

struct MappedPhoneme {
  int phoneme;  // model phoneme index; -1 for a label the phone set does not know
  std::int64_t start_us;
};

inline std::vector<MappedPhoneme> map_phonemes(const LabeledUtterance& utterance, const PhoneSet& set, int silence) {
  std::vector<MappedPhoneme> mapped;
  for (const LabeledInterval& interval : utterance.intervals) {
    const int phoneme = set.lookup(interval.label).value_or(-1);
    if (phoneme == silence && !mapped.empty() && mapped.back().phoneme == silence) continue;
    mapped.push_back({phoneme, interval.start_us});
  }
  return mapped;
}

/// Adds the boundaries of one utterance to `score`.
inline void score_alignment(const LabeledUtterance& reference, const PhoneSet& reference_set,
                            const LabeledUtterance& aligned, const PhoneSet& aligned_set,
                            const ArticulationModel& model, BoundaryScore& score) {
  const int silence = model.silence_phoneme();
  const std::vector<MappedPhoneme> ref = map_phonemes(reference, reference_set, silence);
  const std::vector<MappedPhoneme> hyp = map_phonemes(aligned, aligned_set, silence);
  const std::size_t n = ref.size(), m = hyp.size();
  std::vector<std::vector<int>> cost(n + 1, std::vector<int>(m + 1, 0));
  for (std::size_t i = 0; i <= n; ++i) cost[i][0] = static_cast<int>(i);
  for (std::size_t j = 0; j <= m; ++j) cost[0][j] = static_cast<int>(j);
  for (std::size_t i = 1; i <= n; ++i) {
    for (std::size_t j = 1; j <= m; ++j) {
      const int same = ref[i - 1].phoneme >= 0 && ref[i - 1].phoneme == hyp[j - 1].phoneme ? 0 : 1;
      cost[i][j] = std::min({cost[i - 1][j - 1] + same, cost[i - 1][j] + 1, cost[i][j - 1] + 1});
    }
  }
  const auto is_bilabial = [&](int phoneme) {
    if (phoneme < 0) return false;
    const std::string& name = model.phonemes()[static_cast<std::size_t>(phoneme)].name;
    return name == "p" || name == "b" || name == "m";
  };
  for (const LabeledInterval& interval : reference.intervals) {
    const int phoneme = reference_set.lookup(interval.label).value_or(-1);
    if (phoneme < 0 || phoneme == silence) continue;
    const bool bilabial = is_bilabial(phoneme);
    score.other_phonemes += bilabial ? 0 : 1;
    const std::int64_t middle_us = (interval.start_us + interval.end_us) / 2;
    for (const LabeledInterval& at : aligned.intervals) {
      if (at.start_us <= middle_us && middle_us < at.end_us) {
        const int shown = is_bilabial(aligned_set.lookup(at.label).value_or(-1)) ? 1 : 0;
        (bilabial ? score.bilabials_closed_at_middle : score.false_closures) += shown;
        break;
      }
    }
  }
  score.reference_phonemes += static_cast<int>(n);
  for (const MappedPhoneme& phoneme : ref) score.bilabials += is_bilabial(phoneme.phoneme) ? 1 : 0;
  for (std::size_t i = n, j = m; i > 0 && j > 0;) {
    const bool equal = ref[i - 1].phoneme >= 0 && ref[i - 1].phoneme == hyp[j - 1].phoneme;
    if (equal && cost[i][j] == cost[i - 1][j - 1]) {
      ++score.matched_phonemes;
      const double signed_ms = double(hyp[j - 1].start_us - ref[i - 1].start_us) / 1000.0;
      const double error_ms = std::abs(signed_ms);
      if (ref[i - 1].start_us > 0) {
        score.errors_ms.push_back(error_ms);
        score.signed_errors_ms.push_back(signed_ms);
      }
      if (is_bilabial(ref[i - 1].phoneme)) {
        score.bilabial_errors_ms.push_back(error_ms);
        if (error_ms <= 20.0) ++score.bilabials_within_20ms;
      }
      --i, --j;
    } else if (cost[i][j] == cost[i - 1][j - 1] + 1) {
      --i, --j;
    } else if (cost[i][j] == cost[i - 1][j] + 1) {
      --i;
    } else {
      --j;
    }
  }
}

/// The `q` quantile (0 to 1) of `values`, nearest rank; 0 for none.
inline double quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  const auto rank = static_cast<std::size_t>(std::ceil(q * double(values.size())));
  return values[std::min(values.size() - 1, rank == 0 ? 0 : rank - 1)];
}

}  // namespace lipsync::testing
