// The closure promise on the simulated face, on real TTS timings (tests/data/closures): the track
// is stepped frame by frame exactly as lipsyncd's mesh stream does (one FaceSolver at subdivision
// level 1, each frame's channels held for the interval since the previous frame), and at every
// bilabial key frame the lips are sealed (inner-lip gap ≤ 0.5 mm over the middle 20 mm of the
// mouth) while at every labiodental key frame the lower lip is within 1 mm of the upper teeth; the
// open vowels still open (≥ 12 mm), and the lips never cross. All of it for the default solve and
// for the fast one (fast_face_solver_params()), which also stays within 0.15 mm of the default on
// average over the skin and lips.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <set>

#include "../support/closure_frames.hpp"
#include "../support/lip_measures.hpp"
#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/face/face_solver.hpp"
#include "lipsync/renderer.hpp"

namespace lipsync::face {
namespace {

using lipsync::testing::ClosurePlace;

constexpr double kSealedM = 0.0005;
constexpr double kTouchingTeethM = 0.001;
constexpr double kOpenVowelM = 0.012;  // issue 41: /aa/ opens at least 12 mm

const ArticulationModel& model() { return ArticulationModel::builtin(); }

const FaceMesh& level1() {
  static const FaceMesh mesh = build_face_mesh(FaceAsset::builtin(), 1);
  return mesh;
}

struct Measured {
  std::size_t bilabial = 0, labiodental = 0;
  double worst_gap_m = 0, worst_teeth_m = 0, widest_aa_m = 0, worst_crossing_m = 0;
};

// Steps `solver` through the track as the server's mesh stream does and measures every closure
// frame and every /aa/ frame of the utterance.
void measure(FaceSolver& solver, const lipsync::testing::TimedUtterance& utterance, int fps, Measured& out) {
  const Track track = render_track(model(), utterance.segments, {.fps = fps});
  // Frame → the places closed there; a frame where two closures meet ("of my": /v/ then /m/) must
  // satisfy both.
  std::map<std::size_t, std::set<ClosurePlace>> closure_at;
  for (const auto& closure : lipsync::testing::closure_frames(model(), utterance.segments, track)) {
    closure_at[closure.frame].insert(closure.place);
  }
  const int aa = *model().find_phoneme("aa");
  solver.reset();
  std::int64_t previous_us = 0;
  std::size_t segment = 0;
  for (std::size_t f = 0; f < track.frame_count(); ++f) {
    solver.step(track.frame_values(f), static_cast<double>(track.t_us[f] - previous_us) * 1e-6);
    previous_us = track.t_us[f];
    out.worst_crossing_m = std::max(out.worst_crossing_m, lip_crossing_m(solver));
    while (segment + 1 < utterance.segments.size() && utterance.segments[segment].end_us <= track.t_us[f]) ++segment;
    if (utterance.segments[segment].phoneme == aa) {
      const auto x = solver.positions();
      out.widest_aa_m = std::max(out.widest_aa_m, distance(x[13], x[14]));
    }
    const auto it = closure_at.find(f);
    if (it == closure_at.end()) continue;
    const std::string where =
        utterance.name + " at " + std::to_string(track.t_us[f]) + " µs, " + std::to_string(fps) + " fps";
    if (it->second.count(ClosurePlace::bilabial)) {
      ++out.bilabial;
      const double gap = lip_gap_m(solver);
      out.worst_gap_m = std::max(out.worst_gap_m, gap);
      EXPECT_LE(gap, kSealedM) << where << ": lips " << 1000 * gap << " mm apart at a bilabial key frame";
    }
    if (it->second.count(ClosurePlace::labiodental)) {
      ++out.labiodental;
      const double reach = lower_lip_to_upper_teeth_m(solver);
      out.worst_teeth_m = std::max(out.worst_teeth_m, reach);
      EXPECT_LE(reach, kTouchingTeethM) << where << ": lower lip " << 1000 * reach << " mm from the upper teeth";
    }
  }
}

void expect_closures_on_real_speech(const FaceSolverParams& params) {
  const auto corpus = lipsync::testing::load_closure_corpus(LIPSYNC_TEST_DATA_DIR, model());
  ASSERT_FALSE(corpus.empty());
  FaceSolver solver(level1(), FaceRig::builtin(), params);
  for (const int fps : {30, 60}) {
    Measured measured;
    for (const auto& utterance : corpus) measure(solver, utterance, fps, measured);
    std::printf(
        "[ measured ] %d iterations, %d fps: %zu bilabial key frames, widest gap %.3f mm; %zu labiodental, farthest "
        "from the teeth %.3f mm; widest /aa/ %.1f mm; lips crossed by at most %.3f mm\n",
        params.iterations, fps, measured.bilabial, 1000 * measured.worst_gap_m, measured.labiodental,
        1000 * measured.worst_teeth_m, 1000 * measured.widest_aa_m, 1000 * measured.worst_crossing_m);
    EXPECT_GE(measured.bilabial, 90U);
    EXPECT_GE(measured.labiodental, 36U);
    EXPECT_GE(measured.widest_aa_m, kOpenVowelM) << "the open vowels no longer open";
    EXPECT_LE(measured.worst_crossing_m, 0.0) << "the lips crossed";
  }
}

TEST(FaceClosures, EveryBilabialKeyFrameIsSealedAndEveryLabiodentalTouchesTheTeethOnRealSpeech) {
  expect_closures_on_real_speech({});
}

TEST(FaceClosures, TheFastSolveKeepsEveryClosureSealedAndTheOpenVowelsOpenOnRealSpeech) {
  expect_closures_on_real_speech(fast_face_solver_params());
}

// The fast solve's poses against the default's, frame by frame on the same real-speech tracks at
// 30 frames/s, over the skin and lips (soft nodes of ring depth ≤ 2; the cavity lining is not
// seen): 0.095 mm on average when measured (docs/performance.md). Its worst node is millimetres
// off (inner-lip nodes at the contacts, as between 5 and 60 iterations), so only the mean is held.
TEST(FaceClosures, TheFastSolveStaysWithinAFractionOfAMillimetreOfTheDefaultOnAverage) {
  const auto corpus = lipsync::testing::load_closure_corpus(LIPSYNC_TEST_DATA_DIR, model());
  ASSERT_FALSE(corpus.empty());
  FaceSolver full(level1(), FaceRig::builtin()), fast(level1(), FaceRig::builtin(), fast_face_solver_params());
  double sum_m = 0;
  std::size_t count = 0;
  for (const auto& utterance : corpus) {
    const Track track = render_track(model(), utterance.segments, {.fps = 30});
    full.reset();
    fast.reset();
    std::int64_t previous_us = 0;
    for (std::size_t f = 0; f < track.frame_count(); ++f) {
      const double dt_s = static_cast<double>(track.t_us[f] - previous_us) * 1e-6;
      previous_us = track.t_us[f];
      full.step(track.frame_values(f), dt_s);
      fast.step(track.frame_values(f), dt_s);
      const auto a = full.positions(), b = fast.positions();
      for (std::size_t i = 0; i < level1().soft_node_count; ++i) {
        if (level1().ring_depth[i] > 2.0) continue;
        sum_m += distance(a[i], b[i]);
        ++count;
      }
    }
  }
  ASSERT_GT(count, 0U);
  const double mean_m = sum_m / static_cast<double>(count);
  std::printf("[ measured ] fast solve vs default: mean %.3f mm over %zu node-frames\n", 1000 * mean_m, count);
  EXPECT_GT(mean_m, 0.0) << "the fast solve computes exactly the default: the test no longer compares two solves";
  EXPECT_LE(mean_m, 0.00015);
}

}  // namespace
}  // namespace lipsync::face
