// Cohen–Massaro coarticulation with the windowing of Albrecht, Haber & Seidel.
//
// The value of channel m at time t is the dominance-weighted mean of the
// targets of the segments around t (Eq. 5):
//
//     F_m(t) = Σ_s D_{s,m}(t) · T_{s,m} / Σ_s D_{s,m}(t)
//
// with D the negative exponential of Eq. 2 for segments up to 6 away from the
// segment c that contains t, a cubic Hermite fade to zero across the 7th
// segment (Eq. 4), and nothing beyond: at most 15 segments per sample.
//
// Numerics (docs/coarticulation.md):
//   - Dominances are handled as logarithms and each channel's weights are
//     scaled by the largest one before exponentiation, so a ten-minute pause
//     (θ·|τ| in the thousands) gives exact 1·T/1 instead of 0/0.
//   - The Hermite fade h(u) = P·u²·((3−2u) + (u−1)·Δ·g) (fade-in; g = D'/D at
//     the border, Δ the segment length) is non-negative on [0,1] iff Δ·g ≤ 3;
//     the slope is clamped to that bound (and to ≥ −3 for the fade-out), so no
//     weight is ever negative and the output is a convex combination.
//   - The result is clamped to the [min, max] of the targets that carry
//     weight, which removes the last-ulp overshoot of the division.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "lipsync/model.hpp"
#include "lipsync/segment.hpp"

namespace lipsync {

/// Segments considered on each side of the current one (6 full + 1 faded).
inline constexpr int kWindowRadius = 7;
/// A channel whose scaled denominator falls below this is recomputed in log space.
inline constexpr double kUnderflowGuard = 1e-200;

/// A model's dominance parameters regrouped for evaluation: each phoneme's
/// channels grouped by dominance shape (θ−, θ+, c, t_off; channels that share
/// one share its exponential), and per shape the rows of α and α·T, padded to
/// whole vector blocks. Building them costs about as much as a hundred frames;
/// they never change, so one instance per model serves every evaluator on
/// every thread (the server builds it once per loaded model).
class CoarticulationTables {
 public:
  explicit CoarticulationTables(const ArticulationModel& model);

  const ArticulationModel& model() const { return model_; }

 private:
  friend class CoarticulationEvaluator;

  const ArticulationModel& model_;
  std::size_t channels_;
  std::size_t padded_channels_;  // channels_ rounded up to whole vector blocks
  // Per phoneme, its distinct dominance shapes (θ−, θ+, c, t_off; α = 1):
  // shapes_[shape_begin_[p] .. shape_begin_[p + 1]).
  std::vector<DominanceParams> shapes_;
  std::vector<std::uint32_t> shape_begin_;
  std::size_t max_shapes_ = 1;
  // Phoneme × padded channel tables.
  std::vector<std::uint32_t> channel_shape_;  // index into the phoneme's shapes
  std::vector<double> target_;
  // Shape × padded channel tables: α and α·T of the channels of that shape, 0 elsewhere.
  std::vector<double> alpha_;
  std::vector<double> alpha_target_;
};

/// Evaluates Eq. 4–5 at instants of one segment. It holds only the shared
/// tables: its scratch space is its thread's, one for all the evaluators that
/// run there (sized once for the largest model seen, so evaluation allocates
/// nothing after a thread's first call). A server runs an evaluator per stream,
/// thousands of them; with scratch of their own, every call would first fetch
/// its stream's few kilobytes from memory (docs/performance.md, "What
/// makes it fast").
class CoarticulationEvaluator {
 public:
  /// Builds the model's tables for this evaluator alone.
  explicit CoarticulationEvaluator(const ArticulationModel& model);
  /// Shares tables built once (their model must outlive them).
  explicit CoarticulationEvaluator(std::shared_ptr<const CoarticulationTables> tables);

  /// Channel values at `t_us`. `window` holds consecutive segments, and
  /// `current` indexes the one that contains t (t may equal the end of the last
  /// segment). Segments further than kWindowRadius from `current` are ignored;
  /// a window shorter on one side (utterance edge, or lookahead) simply has
  /// fewer contributors. Times, t's and the segments', lie within ±kMaxTimeUs
  /// (as SegmentBuilder ensures). Writes channel_count() values to `out`.
  void evaluate(std::span<const Segment> window, std::size_t current, std::int64_t t_us, std::span<float> out) {
    evaluate(window, current, std::span<const std::int64_t>(&t_us, 1), out);
  }
  /// The same for several instants in segment `current`: writes one row of
  /// channel_count() values per time, in order. Each row is the very value of
  /// a call for its time alone; the instants share the walk over the window,
  /// four at a time (the renderers pass all the frames of a segment).
  void evaluate(std::span<const Segment> window, std::size_t current, std::span<const std::int64_t> t_us,
                std::span<float> out);

 private:
  struct Scratch;
  void evaluate_lanes(Scratch& scratch, std::span<const Segment> window, std::size_t current,
                      std::span<const std::int64_t> t_us, std::span<float> out);
  void evaluate_channel_in_log_space(Scratch& scratch, std::span<const Segment> window, std::size_t first,
                                     std::size_t last, std::size_t channel, const double* scaled_log_shape);

  std::shared_ptr<const CoarticulationTables> tables_;
};

/// The Hermite fade of Eq. 4 divided by the border dominance P, for u ∈ [0, 1]
/// across a segment of `length_s` seconds, with `slope_per_s` = D'/D at the
/// border. The slope is first clamped so that the result is never negative.
/// Fade-in (in s₋₇, 0 at u = 0, 1 at u = 1): u² · ((3 − 2u) + (u − 1) · Δ · g), g ≤ 3/Δ.
double fade_in_shape(double u, double length_s, double slope_per_s);
/// Fade-out (in s₊₇, 1 at u = 0, 0 at u = 1): (1 − u)² · ((1 + 2u) + u · Δ · g), g ≥ −3/Δ.
double fade_out_shape(double u, double length_s, double slope_per_s);

/// y[i] = e^x[i] for x[i] ≤ 0 (−∞ allowed), within 2 ulp of std::exp, and 0
/// where e^x would be subnormal (x < −708). The evaluator's weights go through
/// the same code in one vectorised batch per frame instead of one libm call each.
void exp_non_positive(std::span<const double> x, std::span<double> y);

/// The original, unwindowed Cohen–Massaro (Eq. 1): every segment of the
/// utterance contributes with the plain exponential dominance. Same log-space
/// normalisation. O(segments) per sample: kept for tests and benchmarks.
void evaluate_unwindowed(const ArticulationModel& model, std::span<const Segment> segments, std::int64_t t_us,
                         std::span<float> out);

}  // namespace lipsync
