// Eq. 2–5 of Albrecht, Haber & Seidel (2002); see lipsync/coarticulation.hpp
// for the numerical safeguards (log-space weights, clamped Hermite slopes).
#include "lipsync/coarticulation.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>

namespace lipsync {
namespace {

constexpr double kNegativeInfinity = -std::numeric_limits<double>::infinity();

/// τ of Eq. 3 in seconds: distance from t to the dominance peak (positive
/// before the peak). Release phonemes peak at the start of their interval
/// (Section 3.2). A closure's peak is its whole hold (Eq. 3′ in
/// docs/coarticulation.md): τ is the distance from t to [t_start, t_end]
/// shifted by t_off, 0 inside, so the closure's dominance is α all through the
/// hold, at both of its key frames, whatever its length. The segment's times
/// and t are combined in integer µs first.
inline double tau_s(const Segment& segment, const DominanceParams& params, std::int64_t t_us) {
  switch (segment.phoneme_class) {
    case PhonemeClass::release:
      return static_cast<double>(segment.start_us - t_us) * 1e-6;
    case PhonemeClass::closure: {
      const double before_start = static_cast<double>(segment.start_us - t_us) * 1e-6 - params.t_off_s;
      if (before_start > 0.0) return before_start;
      const double before_end = static_cast<double>(segment.end_us - t_us) * 1e-6 - params.t_off_s;
      return before_end < 0.0 ? before_end : 0.0;
    }
    default:
      return static_cast<double>(segment.start_us + segment.end_us - 2 * t_us) * 0.5e-6 - params.t_off_s;
  }
}

inline double power(double base, double exponent) {
  if (exponent == 1.0) return base;
  if (exponent == 0.0) return 1.0;
  if (exponent == 2.0) return base * base;
  return std::pow(base, exponent);
}

/// log D of Eq. 2: log α − θ± · |τ|^c, with θ+ while rising (τ ≥ 0).
inline double log_dominance(const DominanceParams& params, double log_alpha, double tau) {
  const double theta = tau >= 0.0 ? params.theta_plus_per_s : params.theta_minus_per_s;
  return log_alpha - theta * power(std::fabs(tau), params.c);
}

/// d(log D)/dt at a segment border. At the peak itself the paper takes the
/// descending side for a left border (`descending_at_peak`) and the ascending
/// side for a right border. On a closure's plateau (τ = 0 over its hold) the
/// dominance is flat.
inline double log_dominance_slope(const Segment& segment, const DominanceParams& params, double tau,
                                  bool descending_at_peak) {
  if (tau == 0.0 && segment.phoneme_class == PhonemeClass::closure) return 0.0;
  // log D = log α − θ |τ|^c with dτ/dt = −1, so d/dt = θ c |τ|^(c−1) sign(τ).
  const bool rising = tau > 0.0 || (tau == 0.0 && !descending_at_peak);
  const double theta = rising ? params.theta_plus_per_s : params.theta_minus_per_s;
  const double magnitude = theta * params.c * power(std::fabs(tau), params.c - 1.0);
  return rising ? magnitude : -magnitude;
}

// Channel tables are padded to a multiple of kLanes (padding: α = 0, target 0)
// so that the loops below run in whole vectors. They are compiled twice,
// for AVX2 and for baseline x86-64, and the loader picks the best the CPU has;
// both give the same numbers (the same operations in the same order per lane).
// Not under GCC's TSan: the loader runs the clones' resolver (an IFUNC) while
// it relocates the program, before the TSan runtime is set up, and TSan
// instruments the resolver too, so every TSan executable died with SIGSEGV
// before main (docs/security.md, "Sanitizers").
constexpr std::size_t kLanes = 4;

/// kLanes doubles: one AVX2 register, or two SSE2 ones. Arithmetic on it is
/// lane by lane, the same IEEE operations as on plain doubles. The channel
/// sums run over channels in lanes; pass 1 runs over up to kLanes frame times.
using Lanes = double __attribute__((vector_size(kLanes * sizeof(double))));
using LaneBits = std::uint64_t __attribute__((vector_size(kLanes * sizeof(std::uint64_t))));
/// What a comparison of two Lanes gives: all ones in a lane where it holds, zero elsewhere.
using LaneMask = std::int64_t __attribute__((vector_size(kLanes * sizeof(std::int64_t))));

/// log D/α of Eq. 2 (log_dominance with log α = 0, of τ = tau_s) for kLanes
/// instants at once, lane by lane the same operations. The instants are whole
/// µs of at most kMaxTimeUs in magnitude, so they, the segment's times and
/// their sums and differences are exact doubles: subtracting in double gives
/// the very value tau_s converts from its integer difference. (The result is
/// written through a reference: GCC warns that a returned Lanes value is
/// passed differently with and without AVX.)
[[gnu::always_inline]] inline void log_dominance_lanes(const Segment& segment, const DominanceParams& params,
                                                       const Lanes& t_us, Lanes& log_dominance) {
  const double start_us = static_cast<double>(segment.start_us);
  const double end_us = static_cast<double>(segment.end_us);
  Lanes tau;
  switch (segment.phoneme_class) {
    case PhonemeClass::release:
      tau = (start_us - t_us) * 1e-6;
      break;
    case PhonemeClass::closure: {
      const Lanes before_start = (start_us - t_us) * 1e-6 - params.t_off_s;
      const Lanes before_end = (end_us - t_us) * 1e-6 - params.t_off_s;
      tau = before_start > 0.0 ? before_start : (before_end < 0.0 ? before_end : Lanes{});
      break;
    }
    default:
      tau = ((start_us + end_us) - 2.0 * t_us) * 0.5e-6 - params.t_off_s;
  }
  const Lanes theta = tau >= 0.0 ? (Lanes{} + params.theta_plus_per_s) : (Lanes{} + params.theta_minus_per_s);
  // |τ|: the sign bit cleared, as std::fabs does.
  LaneBits bits;
  std::memcpy(&bits, &tau, sizeof bits);
  bits &= ~(LaneBits{} + (1ULL << 63));
  Lanes base;
  std::memcpy(&base, &bits, sizeof base);
  Lanes raised;
  if (params.c == 1.0) {
    raised = base;
  } else if (params.c == 0.0) {
    raised = Lanes{} + 1.0;
  } else if (params.c == 2.0) {
    raised = base * base;
  } else {
    for (std::size_t lane = 0; lane < kLanes; ++lane) raised[lane] = std::pow(base[lane], params.c);
  }
  log_dominance = 0.0 - theta * raised;
}

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
#define LIPSYNC_VECTOR_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define LIPSYNC_VECTOR_CLONES
#endif

/// One frame's window as the sums of Eq. 5 see it: pointers into the tables
/// and into the evaluator's scratch, which pass 1 has filled.
struct FrameSums {
  std::size_t padded_channels;
  const double* alpha;              // shape × padded channel: α of the shape's channels, 0 elsewhere
  const double* alpha_target;       // shape × padded channel: α · T, likewise
  const double* target;             // phoneme × padded channel: T
  const double* weight;             // per slot (a shape of a window segment): exp(log D/α − max), or 0
  const std::size_t* slot_row;      // per slot: where its shape's row starts in alpha and alpha_target
  const std::size_t* slot_targets;  // per slot: where its segment's phoneme's row starts in target
  std::size_t slots;
  double* numerator;  // per padded channel, written
  double* denominator;
  double* low;
  double* high;
};

/// Whether a comparison held in any lane.
inline bool any_lane(const LaneMask& mask) {
  static_assert(kLanes == 4, "any_lane reads four lanes");
  return (mask[0] | mask[1] | mask[2] | mask[3]) != 0;
}

/// `lanes` = p[0 .. kLanes) (any alignment), and back.
inline void load(Lanes& lanes, const double* p) { std::memcpy(&lanes, p, sizeof lanes); }
inline void store(const Lanes& lanes, double* p) { std::memcpy(p, &lanes, sizeof lanes); }

/// Eq. 5's sums for channels [first_channel, first_channel + kWidth) of one
/// frame. For each slot, in slot order: numerator += α·T · w and denominator +=
/// α · w (the rows of the slot's shape: channels of other shapes have α = 0
/// there). A term that is zero (α = 0, or w = 0: a segment so far away that its
/// weight underflowed) changes no sum, not even the sign of a zero one: the sums
/// start at +0, x + ±0 = x for x ≠ 0 and +0 + ±0 = +0, so no sum is ever −0.
/// So every slot is added, without a test. With kRange, each channel's [low,
/// high] is widened to the target of each slot with a nonzero weight (a segment
/// far away in time adds nothing, and its targets do not bound the result;
/// widening again by the target of the segment's next shape changes nothing);
/// without, [low, high] is left as it is (another frame with the same
/// contributors has set it). kWidth is a constant, and the loops over it are
/// unrolled, so that the accumulators stay in registers across all the frame's
/// slots instead of a call and a round trip through memory per shape.
template <std::size_t kWidth, bool kRange>
[[gnu::always_inline]] inline void sum_block(const FrameSums& frame, std::size_t first_channel) {
  constexpr std::size_t kVectors = kWidth / kLanes;
  const double* const alpha = frame.alpha + first_channel;
  const double* const alpha_target = frame.alpha_target + first_channel;
  const double* const target = frame.target + first_channel;
  const double* const weight = frame.weight;
  const std::size_t slots = frame.slots;
  Lanes numerator[kVectors] = {};
  Lanes denominator[kVectors] = {};
  Lanes low[kVectors];
  Lanes high[kVectors];
#pragma GCC unroll 16
  for (std::size_t v = 0; v < kVectors; ++v) {
    low[v] = Lanes{} + std::numeric_limits<double>::infinity();
    high[v] = Lanes{} - std::numeric_limits<double>::infinity();
  }
  for (std::size_t slot = 0; slot < slots; ++slot) {
    const double w = weight[slot];
    const double* slot_alpha_target = alpha_target + frame.slot_row[slot];
    const double* slot_alpha = alpha + frame.slot_row[slot];
#pragma GCC unroll 16
    for (std::size_t v = 0; v < kVectors; ++v) {
      Lanes lanes;
      load(lanes, slot_alpha_target + v * kLanes);
      numerator[v] += lanes * w;
      load(lanes, slot_alpha + v * kLanes);
      denominator[v] += lanes * w;
    }
    if constexpr (kRange) {
      if (w == 0.0) continue;
      const double* slot_target = target + frame.slot_targets[slot];
#pragma GCC unroll 16
      for (std::size_t v = 0; v < kVectors; ++v) {
        Lanes lanes;
        load(lanes, slot_target + v * kLanes);
        low[v] = lanes < low[v] ? lanes : low[v];
        high[v] = lanes > high[v] ? lanes : high[v];
      }
    }
  }
#pragma GCC unroll 16
  for (std::size_t v = 0; v < kVectors; ++v) {
    const std::size_t c = first_channel + v * kLanes;
    store(numerator[v], frame.numerator + c);
    store(denominator[v], frame.denominator + c);
    if constexpr (kRange) {
      store(low[v], frame.low + c);
      store(high[v], frame.high + c);
    }
  }
}

template <bool kRange>
[[gnu::always_inline]] inline void sum_frame_blocks(const FrameSums& frame) {
  constexpr std::size_t kBlock = 4 * kLanes;
  std::size_t c = 0;
  for (; c + kBlock <= frame.padded_channels; c += kBlock) sum_block<kBlock, kRange>(frame, c);
  for (; c < frame.padded_channels; c += kLanes) sum_block<kLanes, kRange>(frame, c);
}

/// Eq. 5's sums for all padded channels, in blocks of 16 (the built-in model's
/// count) and then of one vector; [low, high] too if `range`.
LIPSYNC_VECTOR_CLONES void sum_frame(const FrameSums& frame, bool range) {
  if (range) {
    sum_frame_blocks<true>(frame);
  } else {
    sum_frame_blocks<false>(frame);
  }
}

/// Splits of ln 2 for the range reduction: k · kLn2Hi is exact for |k| < 2^11.
constexpr double kLn2Hi = 0x1.62e42fee00000p-1;
constexpr double kLn2Lo = 0x1.a39ef35793c76p-33;
constexpr double kLog2E = 0x1.71547652b82fep0;
/// Adding 1.5 · 2^52 rounds to an integer and leaves it in the low mantissa bits.
constexpr double kRoundingShift = 0x1.8p52;
/// Below this e^x is subnormal; such weights are negligible next to the largest (1).
constexpr double kSmallestExponent = -708.0;

}  // namespace

namespace {

/// e^v for v in [−708, 0]: e^v = 2^k · e^r with k = round(v / ln 2) and
/// |r| ≤ ln 2 / 2, e^r by its Taylor series to degree 12 (truncation error
/// below 2·10⁻¹⁶). Straight-line arithmetic, so the loops over it vectorise.
inline double exp_in_range(double v) {
  const double shifted = v * kLog2E + kRoundingShift;
  const double k = shifted - kRoundingShift;
  const double r = (v - k * kLn2Hi) - k * kLn2Lo;
  double p = 1.0 / 479001600.0;
  p = p * r + 1.0 / 39916800.0;
  p = p * r + 1.0 / 3628800.0;
  p = p * r + 1.0 / 362880.0;
  p = p * r + 1.0 / 40320.0;
  p = p * r + 1.0 / 5040.0;
  p = p * r + 1.0 / 720.0;
  p = p * r + 1.0 / 120.0;
  p = p * r + 1.0 / 24.0;
  p = p * r + 1.0 / 6.0;
  p = p * r + 0.5;
  p = p * r + 1.0;
  p = p * r + 1.0;
  // 2^k from the integer in the low bits of `shifted`: exponent field k + 1023.
  return p * std::bit_cast<double>((std::bit_cast<std::uint64_t>(shifted) + 1023) << 52);
}

/// y[i] = e^x[i] for x[i] ≤ 0, and 0 where e^x would be subnormal. Three
/// loops, so that each of them vectorises (in one, GCC branches on the select).
LIPSYNC_VECTOR_CLONES void exp_or_zero(const double* __restrict x, double* __restrict y, std::size_t count) {
  for (std::size_t i = 0; i < count; ++i) y[i] = std::max(x[i], kSmallestExponent);
  for (std::size_t i = 0; i < count; ++i) y[i] = exp_in_range(y[i]);
  for (std::size_t i = 0; i < count; ++i) y[i] = x[i] < kSmallestExponent ? 0.0 : y[i];
}

/// The weights of the slots of the first `lanes` instants: from log_shape, kLanes values per
/// slot (slot × lane), scaled[lane][slot] = log_shape[slot][lane] − max_log[lane], and weight =
/// e^scaled (or 0), instant after instant (lane × slot): each instant's weights are contiguous,
/// and none are computed for lanes past the instants.
LIPSYNC_VECTOR_CLONES void shape_weights(const double* __restrict log_shape, const double* __restrict max_log,
                                         std::size_t lanes, std::size_t slots, double* __restrict scaled,
                                         double* __restrict weight) {
  for (std::size_t lane = 0; lane < lanes; ++lane) {
    for (std::size_t slot = 0; slot < slots; ++slot) {
      scaled[lane * slots + slot] = log_shape[slot * kLanes + lane] - max_log[lane];
    }
  }
  exp_or_zero(scaled, weight, lanes * slots);
}

/// Pass 1 of an evaluation for up to kLanes instants in one segment, one per lane.
struct WindowLogs {
  const Segment* window;
  std::size_t first;  // the window's segments [first, last] are those the instants see
  std::size_t last;
  std::size_t current;               // the segment that contains them
  const DominanceParams* shapes;     // the tables' shapes (α = 1)
  const std::uint32_t* shape_begin;  // per phoneme, its first shape
  std::size_t padded_channels;       // the length of a row of the tables
  std::int64_t t_us[kLanes];         // the instants; lanes past `times` repeat the last
  std::size_t times;                 // how many instants there are
  double* log_shape;                 // written: per slot, kLanes values of log D/α
  std::size_t* slot_row;             // written: per slot, where its shape's row starts (shape × padded)
  std::size_t* slot_targets;         // written: per slot, where its phoneme's row starts (phoneme × padded)
  std::size_t* slot_begin;           // written: per window segment from `first`, its first slot; then the end
  double max_log[kLanes];            // written: per lane, the largest log D/α
};

/// log D / α for every segment of the window and every shape of its phoneme
/// (Eq. 2, or Eq. 4's Hermite fade for the 7th segment on each side), for each
/// instant in its lane, packed: each segment's shapes follow the previous
/// segment's, so the passes after it touch only the shapes there are (about
/// 18 of the 15 × max_shapes slots). Returns the number of slots.
LIPSYNC_VECTOR_CLONES std::size_t window_log_dominances(WindowLogs& logs) {
  // Read once: GCC cannot tell the stores below from these fields.
  double* const log_shape = logs.log_shape;
  std::size_t* const slot_row = logs.slot_row;
  std::size_t* const slot_targets = logs.slot_targets;
  std::size_t* const slot_begin = logs.slot_begin;
  const Segment* const window = logs.window;
  const DominanceParams* const shapes = logs.shapes;
  const std::uint32_t* const shape_begin = logs.shape_begin;
  const std::size_t padded = logs.padded_channels;
  const std::size_t first = logs.first;
  const std::size_t last = logs.last;
  const std::size_t current = logs.current;
  const std::size_t times = logs.times;
  const Segment& here = window[current];
  const double here_length_s = static_cast<double>(here.end_us - here.start_us) * 1e-6;
  Lanes t;
  for (std::size_t lane = 0; lane < kLanes; ++lane) t[lane] = static_cast<double>(logs.t_us[lane]);
  // u of the Hermite fades, exact like τ (see log_dominance_lanes).
  const Lanes u = (t - static_cast<double>(here.start_us)) /
                  (static_cast<double>(here.end_us) - static_cast<double>(here.start_us));
  // value = one of the fades of Eq. 4, e^(border log D) × shape(u), as a logarithm, for the
  // instants there are (a libm log each), copied to the lanes past them.
  const auto fade = [&](Lanes& value, double border, auto shape) {
    for (std::size_t lane = 0; lane < times; ++lane) value[lane] = border + std::log(shape(u[lane]));
    for (std::size_t lane = times; lane < kLanes; ++lane) value[lane] = value[times - 1];
  };
  Lanes max_log = Lanes{} + kNegativeInfinity;
  std::size_t slots = 0;
  for (std::size_t i = first; i <= last; ++i) {
    const Segment& segment = window[i];
    const auto phoneme = static_cast<std::size_t>(segment.phoneme);
    const std::ptrdiff_t distance = static_cast<std::ptrdiff_t>(i) - static_cast<std::ptrdiff_t>(current);
    slot_begin[i - first] = slots;
    const std::size_t targets = phoneme * padded;
    for (std::uint32_t k = shape_begin[phoneme]; k < shape_begin[phoneme + 1]; ++k, ++slots) {
      const DominanceParams& params = shapes[k];
      Lanes value;
      if (distance == kWindowRadius) {
        // t lies in s₋₇ of this segment: fade in across the current segment,
        // from 0 at its start to D at its end (= start of s₋₆).
        const double tau_border = tau_s(segment, params, here.end_us);
        const double slope = log_dominance_slope(segment, params, tau_border, true);
        fade(value, log_dominance(params, 0.0, tau_border),
             [&](double at) { return fade_in_shape(at, here_length_s, slope); });
      } else if (distance == -kWindowRadius) {
        // t lies in s₊₇: fade out from D at the current segment's start (= end of s₊₆).
        const double tau_border = tau_s(segment, params, here.start_us);
        const double slope = log_dominance_slope(segment, params, tau_border, false);
        fade(value, log_dominance(params, 0.0, tau_border),
             [&](double at) { return fade_out_shape(at, here_length_s, slope); });
      } else {
        log_dominance_lanes(segment, params, t, value);
      }
      store(value, log_shape + slots * kLanes);
      slot_row[slots] = k * padded;
      slot_targets[slots] = targets;
      max_log = max_log < value ? value : max_log;  // std::max, lane by lane
    }
  }
  slot_begin[last - first + 1] = slots;
  store(max_log, logs.max_log);
  return slots;
}

/// Whether the slots with a nonzero weight are the same for each of `lanes` instants (weights
/// lane × slot). Four slots per vector and no early exit: the answer is nearly always yes.
LIPSYNC_VECTOR_CLONES bool lanes_share_contributors(const double* weight, std::size_t slots, std::size_t lanes) {
  LaneMask differ{};
  bool differ_tail = false;
  for (std::size_t lane = 1; lane < lanes; ++lane) {
    const double* other = weight + lane * slots;
    std::size_t slot = 0;
    for (; slot + kLanes <= slots; slot += kLanes) {
      Lanes first;
      Lanes next;
      load(first, weight + slot);
      load(next, other + slot);
      differ |= (first == 0.0) ^ (next == 0.0);
    }
    for (; slot < slots; ++slot) differ_tail |= (weight[slot] == 0.0) != (other[slot] == 0.0);
  }
  return !differ_tail && !any_lane(differ);
}

/// Whether any of the first `count` denominators fell below kUnderflowGuard: one vector
/// test per four channels, so that the loop that handles such channels runs only when needed.
LIPSYNC_VECTOR_CLONES bool any_underflow(const double* denominator, std::size_t count) {
  LaneMask below{};
  std::size_t c = 0;
  for (; c + kLanes <= count; c += kLanes) {
    Lanes lanes;
    load(lanes, denominator + c);
    below |= lanes < kUnderflowGuard;
  }
  bool any = any_lane(below);
  for (; c < count; ++c) any |= denominator[c] < kUnderflowGuard;
  return any;
}

}  // namespace

void exp_non_positive(std::span<const double> x, std::span<double> y) { exp_or_zero(x.data(), y.data(), x.size()); }

namespace {

bool same_shape(const DominanceParams& a, const DominanceParams& b) {
  return a.theta_minus_per_s == b.theta_minus_per_s && a.theta_plus_per_s == b.theta_plus_per_s && a.c == b.c &&
         a.t_off_s == b.t_off_s;
}

}  // namespace

double fade_in_shape(double u, double length_s, double slope_per_s) {
  const double slope = std::min(slope_per_s, 3.0 / length_s);
  return u * u * std::max(0.0, (3.0 - 2.0 * u) + (u - 1.0) * length_s * slope);
}

double fade_out_shape(double u, double length_s, double slope_per_s) {
  const double slope = std::max(slope_per_s, -3.0 / length_s);
  const double v = 1.0 - u;
  return v * v * std::max(0.0, (1.0 + 2.0 * u) + u * length_s * slope);
}

CoarticulationTables::CoarticulationTables(const ArticulationModel& model)
    : model_(model),
      channels_(model.channel_count()),
      padded_channels_((model.channel_count() + kLanes - 1) / kLanes * kLanes) {
  // Group each phoneme's channels by dominance shape (θ−, θ+, c, t_off): the
  // default model gives most phonemes one or two shapes for 16 channels, and
  // exp() is then taken once per shape instead of once per channel.
  const std::size_t phonemes = model.phonemes().size();
  shape_begin_.reserve(phonemes + 1);
  channel_shape_.reserve(phonemes * padded_channels_);
  target_.reserve(phonemes * padded_channels_);
  shape_begin_.push_back(0);
  for (const PhonemeSpec& phoneme : model.phonemes()) {
    const std::size_t first_shape = shapes_.size();
    for (std::size_t c = 0; c < padded_channels_; ++c) {
      const bool real = c < channels_;
      std::size_t local = 0;
      if (real) {
        DominanceParams shape = phoneme.dominance[c];
        shape.alpha = 1.0;
        while (first_shape + local < shapes_.size() && !same_shape(shapes_[first_shape + local], shape)) ++local;
        if (first_shape + local == shapes_.size()) shapes_.push_back(shape);
      }
      channel_shape_.push_back(static_cast<std::uint32_t>(local));
      target_.push_back(real ? phoneme.targets[c] : 0.0);
    }
    // One row of α and α·T per shape, zero for the channels of other shapes
    // and for the padding.
    for (std::size_t k = first_shape; k < shapes_.size(); ++k) {
      for (std::size_t c = 0; c < padded_channels_; ++c) {
        const bool in_shape =
            c < channels_ && channel_shape_[channel_shape_.size() - padded_channels_ + c] == k - first_shape;
        alpha_.push_back(in_shape ? phoneme.dominance[c].alpha : 0.0);
        alpha_target_.push_back(in_shape ? phoneme.dominance[c].alpha * phoneme.targets[c] : 0.0);
      }
    }
    shape_begin_.push_back(static_cast<std::uint32_t>(shapes_.size()));
    max_shapes_ = std::max(max_shapes_, shapes_.size() - first_shape);
  }
}

CoarticulationEvaluator::CoarticulationEvaluator(const ArticulationModel& model)
    : CoarticulationEvaluator(std::make_shared<const CoarticulationTables>(model)) {}

/// An evaluation's working space. One slot per dominance shape of each segment in the window,
/// segment after segment with no gaps; segment i of the window starts at slot_begin[i].
/// slot_row holds where each slot's shape's row starts in the tables' α and α·T, slot_targets
/// where its segment's phoneme's row starts in the targets. log_shape holds log(D/α) of each
/// slot for the (up to) four instants evaluated together, slot after slot; scaled_log_shape
/// the same less each instant's largest, and shape_weight their exponentials, instant after
/// instant. numerator, denominator, low and high: Eq. 5's sums and the clamp's range, per
/// padded channel. Nothing in it outlives a call of evaluate.
struct CoarticulationEvaluator::Scratch {
  std::vector<double> log_shape;
  std::vector<double> scaled_log_shape;
  std::vector<double> shape_weight;
  std::vector<std::size_t> slot_row;
  std::vector<std::size_t> slot_targets;
  std::array<std::size_t, 2 * kWindowRadius + 2> slot_begin{};
  std::vector<double> numerator;
  std::vector<double> denominator;
  std::vector<double> low;
  std::vector<double> high;

  /// Grows, if it must, to hold an evaluation with tables of these sizes.
  void fit(std::size_t max_shapes, std::size_t padded_channels) {
    const std::size_t slots = (2 * kWindowRadius + 1) * max_shapes;
    if (slot_row.size() < slots) {
      log_shape.resize(slots * kLanes);
      scaled_log_shape.resize(slots * kLanes);
      shape_weight.resize(slots * kLanes);
      slot_row.resize(slots);
      slot_targets.resize(slots);
    }
    if (numerator.size() < padded_channels) {
      numerator.resize(padded_channels);
      denominator.resize(padded_channels);
      low.resize(padded_channels);
      high.resize(padded_channels);
    }
  }
};

CoarticulationEvaluator::CoarticulationEvaluator(std::shared_ptr<const CoarticulationTables> tables)
    : tables_(std::move(tables)) {}

void CoarticulationEvaluator::evaluate(std::span<const Segment> window, std::size_t current,
                                       std::span<const std::int64_t> t_us, std::span<float> out) {
  const std::size_t channels = tables_->channels_;
  assert(out.size() >= t_us.size() * channels);
  // The thread's scratch: hot in its caches whichever of its streams calls.
  thread_local Scratch scratch;
  scratch.fit(tables_->max_shapes_, tables_->padded_channels_);
  for (std::size_t done = 0; done < t_us.size(); done += kLanes) {
    const std::size_t count = std::min(kLanes, t_us.size() - done);
    evaluate_lanes(scratch, window, current, t_us.subspan(done, count), out.subspan(done * channels, count * channels));
  }
}

void CoarticulationEvaluator::evaluate_lanes(Scratch& scratch, std::span<const Segment> window, std::size_t current,
                                             std::span<const std::int64_t> t_us, std::span<float> out) {
  assert(current < window.size() && !t_us.empty() && t_us.size() <= kLanes);
  const CoarticulationTables& tables = *tables_;
  const std::size_t channels = tables.channels_;
  const std::size_t first = current >= kWindowRadius ? current - kWindowRadius : 0;
  const std::size_t last = std::min(window.size() - 1, current + kWindowRadius);
  WindowLogs logs{.window = window.data(),
                  .first = first,
                  .last = last,
                  .current = current,
                  .shapes = tables.shapes_.data(),
                  .shape_begin = tables.shape_begin_.data(),
                  .padded_channels = tables.padded_channels_,
                  .t_us = {},
                  .times = t_us.size(),
                  .log_shape = scratch.log_shape.data(),
                  .slot_row = scratch.slot_row.data(),
                  .slot_targets = scratch.slot_targets.data(),
                  .slot_begin = scratch.slot_begin.data(),
                  .max_log = {}};
  // Lanes past the last time repeat it; their results are dropped.
  for (std::size_t lane = 0; lane < kLanes; ++lane) logs.t_us[lane] = t_us[std::min(lane, t_us.size() - 1)];
  const std::size_t slots = window_log_dominances(logs);

  // Pass 2: Eq. 5 with weights α · exp(log D/α − max): the largest shape
  // weight is 1, so nothing overflows and, for all but pathological inputs,
  // every channel's denominator stays far from underflow. Each channel's sums
  // run over the slots in window order, one shape after the other.
  shape_weights(scratch.log_shape.data(), logs.max_log, t_us.size(), slots, scratch.scaled_log_shape.data(),
                scratch.shape_weight.data());
  // The range of the targets that carry weight is the first instant's for all
  // of them when the same slots carry weight for all (nearly always), unless
  // the log-space path has replaced a channel's range with its own.
  const bool same_contributors = lanes_share_contributors(scratch.shape_weight.data(), slots, t_us.size());
  bool range_shared = false;  // scratch.low and .high hold the range of the slots that carry weight
  for (std::size_t lane = 0; lane < t_us.size(); ++lane) {
    sum_frame({.padded_channels = tables.padded_channels_,
               .alpha = tables.alpha_.data(),
               .alpha_target = tables.alpha_target_.data(),
               .target = tables.target_.data(),
               .weight = scratch.shape_weight.data() + lane * slots,
               .slot_row = scratch.slot_row.data(),
               .slot_targets = scratch.slot_targets.data(),
               .slots = slots,
               .numerator = scratch.numerator.data(),
               .denominator = scratch.denominator.data(),
               .low = scratch.low.data(),
               .high = scratch.high.data()},
              !range_shared);
    range_shared = same_contributors;
    if (any_underflow(scratch.denominator.data(), channels)) {
      for (std::size_t c = 0; c < channels; ++c) {
        if (scratch.denominator[c] < kUnderflowGuard) {
          evaluate_channel_in_log_space(scratch, window, first, last, c,
                                        scratch.scaled_log_shape.data() + lane * slots);
          range_shared = false;
        }
      }
    }
    float* row = out.data() + lane * channels;
    for (std::size_t c = 0; c < channels; ++c) {
      // Clamping to the contributing targets removes the division's last-ulp overshoot.
      row[c] = static_cast<float>(
          std::clamp(scratch.numerator[c] / scratch.denominator[c], scratch.low[c], scratch.high[c]));
    }
  }
}

void CoarticulationEvaluator::evaluate_channel_in_log_space(Scratch& scratch, std::span<const Segment> window,
                                                            std::size_t first, std::size_t last, std::size_t channel,
                                                            const double* scaled_log_shape) {
  // The slow, always-safe path: this channel's weights scaled by their own
  // largest, as logarithms. Taken only when the shared scaling underflowed
  // (shapes of one phoneme that differ by hundreds of orders of magnitude).
  const CoarticulationTables& tables = *tables_;
  const std::size_t padded = tables.padded_channels_;
  double max_log = kNegativeInfinity;
  const auto log_weight = [&](std::size_t i) {
    const auto phoneme = static_cast<std::size_t>(window[i].phoneme);
    const std::size_t shape = tables.channel_shape_[phoneme * padded + channel];
    const double alpha = tables.alpha_[(tables.shape_begin_[phoneme] + shape) * padded + channel];
    return std::log(alpha) + scaled_log_shape[scratch.slot_begin[i - first] + shape];
  };
  for (std::size_t i = first; i <= last; ++i) max_log = std::max(max_log, log_weight(i));
  double numerator = 0.0;
  double denominator = 0.0;
  double low = std::numeric_limits<double>::infinity();
  double high = -std::numeric_limits<double>::infinity();
  for (std::size_t i = first; i <= last; ++i) {
    const double weight = std::exp(log_weight(i) - max_log);
    if (weight == 0.0) continue;
    const double target = tables.target_[static_cast<std::size_t>(window[i].phoneme) * padded + channel];
    numerator += weight * target;
    denominator += weight;
    low = std::min(low, target);
    high = std::max(high, target);
  }
  scratch.numerator[channel] = numerator;
  scratch.denominator[channel] = denominator;
  scratch.low[channel] = low;
  scratch.high[channel] = high;
}

void evaluate_unwindowed(const ArticulationModel& model, std::span<const Segment> segments, std::int64_t t_us,
                         std::span<float> out) {
  const std::size_t channels = model.channel_count();
  std::vector<double> log_weight(segments.size() * channels);
  std::vector<double> max_log(channels, kNegativeInfinity);
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const PhonemeSpec& spec = model.phoneme(segments[i].phoneme);
    for (std::size_t c = 0; c < channels; ++c) {
      const DominanceParams& params = spec.dominance[c];
      const double value = log_dominance(params, std::log(params.alpha), tau_s(segments[i], params, t_us));
      log_weight[i * channels + c] = value;
      max_log[c] = std::max(max_log[c], value);
    }
  }
  for (std::size_t c = 0; c < channels; ++c) {
    double numerator = 0.0;
    double denominator = 0.0;
    for (std::size_t i = 0; i < segments.size(); ++i) {
      const double weight = std::exp(log_weight[i * channels + c] - max_log[c]);
      numerator += weight * model.phoneme(segments[i].phoneme).targets[c];
      denominator += weight;
    }
    out[c] = static_cast<float>(numerator / denominator);
  }
}

}  // namespace lipsync
