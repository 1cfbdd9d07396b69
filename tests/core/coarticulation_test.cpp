#include "lipsync/coarticulation.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "random_segments.hpp"
#include "test_model.hpp"

namespace lipsync {
namespace {

using testing::make_segments;
using testing::test_model;

/// The channel values at `t_us`, as `evaluator` (of `model`) gives them with all of `segments`
/// as the window.
std::vector<float> values_at(CoarticulationEvaluator& evaluator, const ArticulationModel& model,
                             const std::vector<Segment>& segments, std::int64_t t_us) {
  std::size_t current = 0;
  while (current + 1 < segments.size() && segments[current].end_us <= t_us) ++current;
  std::vector<float> out(model.channel_count());
  evaluator.evaluate(segments, current, t_us, out);
  return out;
}

std::vector<float> evaluate_at(const std::vector<Segment>& segments, std::int64_t t_us) {
  CoarticulationEvaluator evaluator(test_model());
  return values_at(evaluator, test_model(), segments, t_us);
}

TEST(Coarticulation, TwoSegmentsGiveASmoothMonotoneTransition) {
  // Paper Fig. 2: targets 0.1 then 0.9, equal dominance functions.
  const auto segments = make_segments(test_model(), {{"low", 0.0, 0.2}, {"high", 0.2, 0.4}});
  std::vector<float> lips;
  for (std::int64_t t = 0; t <= 400'000; t += 1'000) lips.push_back(evaluate_at(segments, t)[0]);
  for (std::size_t i = 1; i < lips.size(); ++i) {
    EXPECT_GE(lips[i], lips[i - 1]) << "decreasing at t = " << i << " ms";
    // Between the two peaks (0.1 s and 0.3 s) the blend moves all the time;
    // outside them (c = 1) the ratio of the two exponentials is constant.
    if (i > 100 && i <= 300) {
      EXPECT_GT(lips[i], lips[i - 1]) << "flat at t = " << i << " ms";
    }
    EXPECT_LT(lips[i] - lips[i - 1], 0.02F) << "jump at t = " << i << " ms";
  }
  EXPECT_NEAR(lips.front(), 0.1, 0.05);
  EXPECT_NEAR(lips[200], 0.5, 1e-6);  // symmetric dominance: the midpoint at the boundary
  EXPECT_NEAR(lips.back(), 0.9, 0.05);
}

TEST(Coarticulation, WindowedEqualsUnwindowedUpToSevenSegments) {
  const ArticulationModel& model = test_model();
  CoarticulationEvaluator evaluator(model);
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const auto segments = testing::random_segments(model, 7, seed);
    for (std::int64_t t = 0; t < segments.back().end_us; t += 7'919) {
      std::size_t current = 0;
      while (segments[current].end_us <= t) ++current;
      std::vector<float> windowed(model.channel_count());
      std::vector<float> reference(model.channel_count());
      evaluator.evaluate(segments, current, t, windowed);
      evaluate_unwindowed(model, segments, t, reference);
      ASSERT_THAT(windowed, ::testing::Pointwise(::testing::FloatNear(1e-6F), reference))
          << "seed " << seed << ", t = " << t << " µs";
    }
  }
}

TEST(Coarticulation, WindowedStaysCloseToUnwindowedOnLongUtterances) {
  const ArticulationModel& model = test_model();
  CoarticulationEvaluator evaluator(model);
  const auto segments = testing::random_segments(model, 400, 7);
  double worst = 0.0;
  std::size_t current = 0;
  for (std::int64_t t = 0; t < segments.back().end_us; t += 10'007) {
    while (segments[current].end_us <= t) ++current;
    std::vector<float> windowed(model.channel_count());
    std::vector<float> reference(model.channel_count());
    evaluator.evaluate(segments, current, t, windowed);
    evaluate_unwindowed(model, segments, t, reference);
    for (std::size_t c = 0; c < windowed.size(); ++c) {
      worst = std::max(worst, static_cast<double>(std::fabs(windowed[c] - reference[c])));
    }
  }
  // Segments 7 away carry almost no weight (θ = 20/s), but very short
  // segments can bring far ones close in time: bound, not zero.
  EXPECT_LT(worst, 0.05);
}

TEST(Coarticulation, OutputIsAConvexCombinationOfTheWindowTargets) {
  const ArticulationModel& model = test_model();
  CoarticulationEvaluator evaluator(model);
  for (std::uint64_t seed = 100; seed < 110; ++seed) {
    const auto segments = testing::random_segments(model, 200, seed);
    std::size_t current = 0;
    for (std::int64_t t = 0; t <= segments.back().end_us; t += 3'001) {
      while (current + 1 < segments.size() && segments[current].end_us <= t) ++current;
      std::vector<float> values(model.channel_count());
      evaluator.evaluate(segments, current, t, values);
      const std::size_t first = current >= 7 ? current - 7 : 0;
      const std::size_t last = std::min(segments.size() - 1, current + 7);
      for (std::size_t c = 0; c < values.size(); ++c) {
        double low = 1e9;
        double high = -1e9;
        for (std::size_t i = first; i <= last; ++i) {
          low = std::min(low, model.phoneme(segments[i].phoneme).targets[c]);
          high = std::max(high, model.phoneme(segments[i].phoneme).targets[c]);
        }
        ASSERT_TRUE(std::isfinite(values[c]));
        ASSERT_GE(values[c], static_cast<float>(low)) << "seed " << seed << " t " << t << " channel " << c;
        ASSERT_LE(values[c], static_cast<float>(high)) << "seed " << seed << " t " << t << " channel " << c;
      }
    }
  }
}

TEST(Coarticulation, TenMinutePauseStaysFiniteAndAtRest) {
  const auto segments = make_segments(test_model(), {{"aa", 0.0, 0.1}, {"sil", 0.1, 600.1}, {"iy", 600.1, 600.2}});
  for (std::int64_t t : {100'000LL, 1'000'000LL, 300'000'000LL, 599'000'000LL, 600'100'000LL - 1}) {
    const auto values = evaluate_at(segments, t);
    for (float v : values) ASSERT_TRUE(std::isfinite(v)) << "t = " << t;
  }
  EXPECT_THAT(evaluate_at(segments, 300'000'000), ::testing::ElementsAre(0.0F, 0.0F, 0.0F));
}

TEST(Coarticulation, TimesFarFromEveryPeakStayFinite) {
  // A single segment of 20 hours: |τ| is huge everywhere but at the centre.
  const auto segments = make_segments(test_model(), {{"high", 0.0, 72'000.0}});
  EXPECT_THAT(evaluate_at(segments, 0), ::testing::ElementsAre(0.9F, 0.9F, 0.5F));
}

TEST(HermiteFade, StartsAtZeroEndsAtOneAndNeverGoesNegative) {
  for (double length_s : {0.001, 0.05, 0.3, 2.0}) {
    for (double slope : {-500.0, -20.0, 0.0, 5.0, 20.0, 60.0, 1e6}) {
      EXPECT_DOUBLE_EQ(fade_in_shape(0.0, length_s, slope), 0.0);
      EXPECT_NEAR(fade_in_shape(1.0, length_s, slope), 1.0, 1e-12);
      EXPECT_NEAR(fade_out_shape(0.0, length_s, slope), 1.0, 1e-12);
      EXPECT_DOUBLE_EQ(fade_out_shape(1.0, length_s, slope), 0.0);
      for (double u = 0.0; u <= 1.0; u += 1.0 / 64) {
        EXPECT_GE(fade_in_shape(u, length_s, slope), 0.0) << "Δ " << length_s << " g " << slope << " u " << u;
        EXPECT_GE(fade_out_shape(u, length_s, -slope), 0.0) << "Δ " << length_s << " g " << -slope << " u " << u;
      }
    }
  }
}

TEST(HermiteFade, MatchesTheDominanceSlopeAtTheBorderWhenNotClamped) {
  // d/du of the fade at the inner border equals Δ·g: the fade joins Eq. 2 with
  // a continuous first derivative (Eq. 4).
  const double length_s = 0.08;
  const double slope = 20.0;  // Δ·g = 1.6 < 3: not clamped
  const double h = 1e-6;
  const double in_derivative = (fade_in_shape(1.0, length_s, slope) - fade_in_shape(1.0 - h, length_s, slope)) / h;
  EXPECT_NEAR(in_derivative, length_s * slope, 1e-4);
  const double out_derivative = (fade_out_shape(h, length_s, -slope) - fade_out_shape(0.0, length_s, -slope)) / h;
  EXPECT_NEAR(out_derivative, -length_s * slope, 1e-4);
}

TEST(Coarticulation, ReleasePeaksAtTheStartOfItsInterval) {
  // p's jaw target is 0.2, silence's 0. With the peak at the centre (0.75 s),
  // jaw would be about 0.13 at 0.5 s and 0.19 at 0.95 s; with the peak at the
  // start it is about 0.2 at 0.5 s and under 0.05 at 0.95 s.
  const auto segments = make_segments(test_model(), {{"sil", 0.0, 0.5}, {"p", 0.5, 1.0}, {"sil", 1.0, 1.5}});
  EXPECT_GT(evaluate_at(segments, 500'000)[1], 0.18F);
  EXPECT_LT(evaluate_at(segments, 950'000)[1], 0.05F);
}

TEST(Coarticulation, IsDeterministic) {
  const ArticulationModel& model = test_model();
  const auto segments = testing::random_segments(model, 50, 3);
  CoarticulationEvaluator a(model);
  CoarticulationEvaluator b(model);
  for (std::int64_t t = 0; t < segments.back().end_us; t += 12'345) {
    std::size_t current = 0;
    while (segments[current].end_us <= t) ++current;
    std::vector<float> first(model.channel_count());
    std::vector<float> second(model.channel_count());
    a.evaluate(segments, current, t, first);
    b.evaluate(segments, current, t, second);
    ASSERT_EQ(first, second);
  }
}

/// A variant of the test model whose dominance exponents are neither 1 nor 2 for some
/// phonemes and channels (std::pow, lane by lane), with offsets and strengths of their own;
/// in "oo" and "ee" the pucker channel's dominance falls so fast that, half a second from
/// their centres, its weights underflow the shared scaling (the log-space path).
const ArticulationModel& exponent_model() {
  static const ArticulationModel model = ArticulationModel::from_json(R"({
    "format": "lipsync-articulation-model", "version": 1, "name": "exponents",
    "channels": [
      {"name": "lips", "kind": "muscle", "min": 0, "max": 1, "rest": 0},
      {"name": "jaw", "kind": "jaw", "min": 0, "max": 1, "rest": 0},
      {"name": "tongue", "kind": "tongue", "min": -1, "max": 1, "rest": 0},
      {"name": "corner", "kind": "muscle", "min": 0, "max": 1, "rest": 0},
      {"name": "pucker", "kind": "muscle", "min": 0, "max": 1, "rest": 0}
    ],
    "dominance_defaults": {"alpha": 1, "theta_minus_per_s": 20, "theta_plus_per_s": 25, "c": 1, "t_off_ms": 0},
    "phonemes": {
      "sil": {"class": "silence", "dominance": {"alpha": 0.5, "c": 1.5}},
      "aa": {"class": "vowel", "targets": {"lips": 0.2, "jaw": 0.8, "tongue": -0.6, "corner": 0.4}},
      "uw": {"class": "vowel", "targets": {"lips": 0.6, "jaw": 0.3, "pucker": 0.9},
             "channel_dominance": {"pucker": {"alpha": 3, "c": 3, "t_off_ms": -15}}},
      "s": {"class": "consonant", "targets": {"tongue": 0.9, "corner": 0.2}, "dominance": {"c": 2}},
      "m": {"class": "closure", "targets": {"lips": 0.9, "jaw": 0.05},
            "channel_dominance": {"lips": {"alpha": 8, "c": 4, "t_off_ms": 5}}},
      "pcl": {"class": "closure", "targets": {"lips": 1.0, "jaw": 0.05}},
      "p": {"class": "release", "closure": "pcl", "targets": {"lips": 0.3, "jaw": 0.2},
            "dominance": {"c": 1.25, "theta_plus_per_s": 60, "theta_minus_per_s": 45}},
      "oo": {"class": "vowel", "targets": {"lips": 0.7, "pucker": 0.9},
             "channel_dominance": {"pucker": {"c": 2, "theta_plus_per_s": 5000, "theta_minus_per_s": 5000}}},
      "ee": {"class": "vowel", "targets": {"lips": 0.1, "pucker": 0.1},
             "channel_dominance": {"pucker": {"c": 2, "theta_plus_per_s": 5000, "theta_minus_per_s": 5000}}}
    },
    "arkit": {"jawOpen": {"weights": {"jaw": 1.0}}}
  })",
                                                                      "exponent test model");
  return model;
}

TEST(Coarticulation, InstantsEvaluatedTogetherGetTheBitsEachGetsAlone) {
  // The renderers hand the evaluator all the frames of a segment at once; each
  // must come out exactly as if it had been evaluated on its own (the stream
  // and the offline render rely on it). Windows cut short on either side, the
  // faded 7th segments, closures, releases and exponents other than 1 and 2
  // are all there; 1 to 9 instants per call cover full and partial groups.
  struct Case {
    const ArticulationModel* model;
    std::vector<Segment> segments;
  };
  const std::vector<Case> cases = {
      {&test_model(), testing::random_segments(test_model(), 40, 11)},
      {&exponent_model(), testing::random_segments(exponent_model(), 40, 11)},
      {&ArticulationModel::builtin(), testing::random_segments(ArticulationModel::builtin(), 40, 11)},
      {&exponent_model(), make_segments(exponent_model(), {{"oo", 0.0, 1.0}, {"ee", 1.0, 2.0}, {"oo", 2.0, 3.0}})},
  };
  for (const auto& [model, segments] : cases) {
    const std::size_t channels = model->channel_count();
    CoarticulationEvaluator together(*model);
    CoarticulationEvaluator alone(*model);
    for (std::size_t current = 0; current < segments.size(); ++current) {
      // The whole utterance, or a window cut 3 segments after the current one (lookahead 3).
      for (const std::size_t after : {segments.size(), current + 4}) {
        const std::span<const Segment> window(segments.data(), std::min(segments.size(), after));
        const std::int64_t start = segments[current].start_us;
        const std::int64_t length = segments[current].end_us - start;
        for (std::size_t count = 1; count <= 9; ++count) {
          std::vector<std::int64_t> times;
          for (std::size_t k = 0; k < count; ++k) {
            times.push_back(start + length * static_cast<std::int64_t>(k) / static_cast<std::int64_t>(count));
          }
          std::vector<float> rows(count * channels);
          together.evaluate(window, current, times, rows);
          std::vector<float> row(channels);
          for (std::size_t k = 0; k < count; ++k) {
            alone.evaluate(window, current, times[k], row);
            ASSERT_EQ(std::memcmp(row.data(), rows.data() + k * channels, channels * sizeof(float)), 0)
                << model->name() << ": segment " << current << ", instant " << k + 1 << " of " << count << " at "
                << times[k] << " us";
          }
        }
      }
    }
  }
}

/// The channel values of frame `frame` of a 30 fps grid over `segments`.
std::vector<float> frame_values(CoarticulationEvaluator& evaluator, const ArticulationModel& model,
                                const std::vector<Segment>& segments, std::size_t frame) {
  return values_at(evaluator, model, segments, static_cast<std::int64_t>(frame) * 1'000'000 / 30);
}

TEST(Coarticulation, EvaluatorsOfDifferentModelsTakingTurnsOnAThreadGetWhatEachGetsAlone) {
  // Evaluators keep no scratch of their own: those on one thread share the thread's, which grows
  // to the largest model the thread has seen. Three models (5 channels with 1 shape per phoneme, 5
  // with up to 3, the built-in 16) take turns frame by frame, the smallest first, on threads of
  // their own and three such threads at once; each frame must be what an evaluator of its model
  // gives on a thread where no other model ever ran.
  const std::vector<const ArticulationModel*> models = {&test_model(), &exponent_model(),
                                                        &ArticulationModel::builtin()};
  std::vector<std::vector<Segment>> segments;
  for (const ArticulationModel* model : models) segments.push_back(testing::random_segments(*model, 30, 5));
  const auto frames_of = [&](std::size_t m) {
    return static_cast<std::size_t>(segments[m].back().end_us * 30 / 1'000'000) + 1;
  };
  std::vector<std::vector<std::vector<float>>> alone(models.size());
  for (std::size_t m = 0; m < models.size(); ++m) {
    std::thread([&, m] {
      CoarticulationEvaluator evaluator(*models[m]);
      for (std::size_t f = 0; f < frames_of(m); ++f) {
        alone[m].push_back(frame_values(evaluator, *models[m], segments[m], f));
      }
    }).join();
  }
  const auto take_turns = [&](std::vector<std::string>& differences) {
    std::vector<CoarticulationEvaluator> evaluators;
    for (const ArticulationModel* model : models) evaluators.emplace_back(*model);
    for (std::size_t f = 0; f < std::max({frames_of(0), frames_of(1), frames_of(2)}); ++f) {
      for (std::size_t m = 0; m < models.size(); ++m) {
        if (f >= frames_of(m)) continue;
        if (frame_values(evaluators[m], *models[m], segments[m], f) != alone[m][f]) {
          differences.push_back(models[m]->name() + ", frame " + std::to_string(f));
        }
      }
    }
  };
  std::vector<std::vector<std::string>> differences(4);
  std::thread(take_turns, std::ref(differences[0])).join();
  std::vector<std::thread> together;
  for (std::size_t i = 1; i < differences.size(); ++i) together.emplace_back(take_turns, std::ref(differences[i]));
  for (std::thread& thread : together) thread.join();
  for (const std::vector<std::string>& thread_differences : differences) {
    EXPECT_THAT(thread_differences, ::testing::IsEmpty());
  }
}

}  // namespace
}  // namespace lipsync

namespace lipsync {
namespace {

TEST(ExpNonPositive, AgreesWithStdExpWithinTwoUlp) {
  std::vector<double> x;
  for (double v = -708.0; v <= 0.0; v += 0.0137) x.push_back(v);
  for (double v : {0.0, -0.0, -1e-300, -1e-17, -0.34657359027997264, -0.3465735902799727, -1.0, -745.0, -1e6,
                   -std::numeric_limits<double>::infinity()}) {
    x.push_back(v);
  }
  std::vector<double> y(x.size());
  exp_non_positive(x, y);
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double expected = x[i] < -708.0 ? 0.0 : std::exp(x[i]);
    ASSERT_NEAR(y[i], expected, 2.0 * std::numeric_limits<double>::epsilon() * expected) << "x = " << x[i];
  }
}

}  // namespace
}  // namespace lipsync
