// face_solver_study: a solver variant against the current solver on real speech, for issue 41's
// levers (docs/performance.md, "The physics face's speed"). Steps the level-1 face through the 30
// files of tests/data/closures at 30 frames/s with key frames, exactly as face_closure_test and the
// server's mesh stream do, and
//   face_solver_study run DUMP [ITERATIONS]   prints the widest bilabial key-frame gap and the
//                                              farthest labiodental lower lip, and writes every
//                                              frame's soft-node positions (doubles) to DUMP;
//   face_solver_study compare REFERENCE DUMP   prints how far DUMP's skin and lips (soft nodes of
//                                              ring depth ≤ 2) are from REFERENCE's: mean and worst
//                                              node over all frames and over the key frames.
// A variant built from other code (a faster solve, a warm start) is compared with the dump of the
// current binary; the same binary at fewer iterations with that of 5.
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "../support/closure_frames.hpp"
#include "../support/lip_measures.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/renderer.hpp"

namespace {

using namespace lipsync;
using namespace lipsync::face;

const FaceMesh& level1() {
  static const FaceMesh mesh = build_face_mesh(FaceAsset::builtin(), 1);
  return mesh;
}

// The corpus rendered at 30 frames/s with key frames, and the closures at each frame.
struct Utterance {
  Track track;
  std::map<std::size_t, std::set<testing::ClosurePlace>> closure_at;
};

std::vector<Utterance> corpus() {
  const ArticulationModel& model = ArticulationModel::builtin();
  std::vector<Utterance> out;
  for (const auto& utterance : testing::load_closure_corpus(LIPSYNC_TEST_DATA_DIR, model)) {
    Utterance u{render_track(model, utterance.segments, {.fps = 30}), {}};
    for (const auto& closure : testing::closure_frames(model, utterance.segments, u.track))
      u.closure_at[closure.frame].insert(closure.place);
    out.push_back(std::move(u));
  }
  return out;
}

bool has(const Utterance& u, std::size_t frame, testing::ClosurePlace place) {
  const auto it = u.closure_at.find(frame);
  return it != u.closure_at.end() && it->second.count(place) > 0;
}

void run(const std::vector<Utterance>& utterances, const std::string& dump_path, int iterations) {
  FaceSolverParams params;
  params.iterations = iterations;
  FaceSolver solver(level1(), FaceRig::builtin(), params);
  std::ofstream dump(dump_path, std::ios::binary);
  double worst_gap_m = 0, worst_teeth_m = 0;
  std::size_t frames = 0, bilabial = 0, labiodental = 0;
  for (const Utterance& u : utterances) {
    solver.reset();
    std::int64_t previous_us = 0;
    for (std::size_t f = 0; f < u.track.frame_count(); ++f, ++frames) {
      solver.step(u.track.frame_values(f), static_cast<double>(u.track.t_us[f] - previous_us) * 1e-6);
      previous_us = u.track.t_us[f];
      const auto x = solver.positions();
      dump.write(reinterpret_cast<const char*>(x.data()),
                 static_cast<std::streamsize>(level1().soft_node_count * sizeof(Vec3)));
      if (has(u, f, testing::ClosurePlace::bilabial)) {
        ++bilabial;
        worst_gap_m = std::max(worst_gap_m, lip_gap_m(solver));
      }
      if (has(u, f, testing::ClosurePlace::labiodental)) {
        ++labiodental;
        worst_teeth_m = std::max(worst_teeth_m, lower_lip_to_upper_teeth_m(solver));
      }
    }
  }
  std::printf(
      "%d iterations: %zu frames; %zu bilabial key frames, widest gap %.3f mm; %zu labiodental, farthest %.3f mm\n",
      iterations, frames, bilabial, 1000 * worst_gap_m, labiodental, 1000 * worst_teeth_m);
}

void compare(const std::vector<Utterance>& utterances, const std::string& reference_path,
             const std::string& dump_path) {
  const FaceMesh& mesh = level1();
  const std::size_t n = mesh.soft_node_count;
  std::ifstream reference(reference_path, std::ios::binary), dump(dump_path, std::ios::binary);
  std::vector<Vec3> a(n), b(n);
  double sum_m = 0, worst_m = 0, key_sum_m = 0, key_worst_m = 0;
  std::size_t count = 0, key_count = 0, beyond = 0;  // beyond: node-frames more than 0.3 mm away
  std::vector<bool> bilabial;
  for (const Utterance& u : utterances)
    for (std::size_t f = 0; f < u.track.frame_count(); ++f)
      bilabial.push_back(has(u, f, testing::ClosurePlace::bilabial));
  for (const bool key : bilabial) {
    reference.read(reinterpret_cast<char*>(a.data()), static_cast<std::streamsize>(n * sizeof(Vec3)));
    dump.read(reinterpret_cast<char*>(b.data()), static_cast<std::streamsize>(n * sizeof(Vec3)));
    if (!reference || !dump) {
      std::fprintf(stderr, "a dump is shorter than the corpus\n");
      return;
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (mesh.ring_depth[i] > 2.0) continue;  // the cavity lining, as in docs/face.md
      const double d = distance(a[i], b[i]);
      sum_m += d;
      worst_m = std::max(worst_m, d);
      ++count;
      if (d > 0.0003) ++beyond;
      if (key) {
        key_sum_m += d;
        key_worst_m = std::max(key_worst_m, d);
        ++key_count;
      }
    }
  }
  std::printf(
      "vs reference: mean %.6f mm, worst node %.6f mm, %.4f %% of nodes beyond 0.3 mm; bilabial key frames: mean "
      "%.6f mm, worst %.6f mm\n",
      1000 * sum_m / static_cast<double>(count), 1000 * worst_m,
      100.0 * static_cast<double>(beyond) / static_cast<double>(count),
      1000 * key_sum_m / static_cast<double>(std::max<std::size_t>(key_count, 1)), 1000 * key_worst_m);
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.size() >= 2 && args.size() <= 3 && args[0] == "run") {
    run(corpus(), args[1], args.size() == 3 ? std::stoi(args[2]) : FaceSolverParams{}.iterations);
    return 0;
  }
  if (args.size() == 3 && args[0] == "compare") {
    compare(corpus(), args[1], args[2]);
    return 0;
  }
  std::fprintf(stderr,
               "usage: face_solver_study run DUMP [ITERATIONS]\n"
               "       face_solver_study compare REFERENCE DUMP\n");
  return 2;
}
