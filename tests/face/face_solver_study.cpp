// face_solver_study: a solver variant against the current solver on real speech, for issue 41's
// levers (docs/performance.md, "The physics face's speed"). Steps the level-1 face through the 30
// files of tests/data/closures at 30 frames/s with key frames, exactly as face_closure_test and the
// server's mesh stream do, and
//   face_solver_study run DUMP [ITERATIONS | fast]
//                                              prints the widest bilabial key-frame gap and the
//                                              farthest labiodental lower lip, and writes every
//                                              frame's soft-node positions (doubles) to DUMP (fast:
//                                              fast_face_solver_params());
//   face_solver_study compare REFERENCE DUMP   prints how far DUMP's skin and lips (soft nodes of
//                                              ring depth ≤ 2) are from REFERENCE's: mean and worst
//                                              node over all frames and over the key frames.
//   face_solver_study subspace DUMP [K...]     the best case of a reduced model (a subspace of the
//                                              soft nodes' displacements): fits a basis to DUMP's
//                                              frames of the files numbered 2, 4, 6 (PCA of the
//                                              displacements from rest), projects the frames of the
//                                              files numbered 1, 3, 5 onto its first K vectors
//                                              (default 10, 20, 40, …, 1280), and
//                                              prints how far the projections are from DUMP, their
//                                              lip gap at the bilabial key frames, and what the dense
//                                              part of a reduced solve of dimension K costs here.
// A variant built from other code (a faster solve, a warm start) is compared with the dump of the
// current binary; the same binary at fewer iterations with that of 5.
//
// Why a projection bounds a reduced model: whatever its equations, a reduced solver in a basis U
// poses the face at rest + U q for some coordinates q, and the orthogonal projection
// rest + U Uᵀ(x − rest) is the pose of that form closest to the full solve's x in the sum of squared
// distances over the soft nodes. Its mean and worst node are those of the best pose in that sense,
// not a strict floor on the worst node (a solver could trade a larger sum for a smaller maximum).
// The strict floor: at any frame, for any set S of nodes, the worst node of every pose in the
// subspace is at least the root mean square over S of the least-squares fit on S alone; the mode
// prints it for S = the lips (skin and lip nodes within 15 mm of the mouth centre at rest). Both hold
// for the PCA basis, the k-dimensional one closest to the fit frames in the same sense.
#include <Eigen/Cholesky>
#include <Eigen/Dense>
#include <algorithm>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <stdexcept>
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
  std::string name;  // file name, e.g. festival_2.lab
  Track track;
  std::map<std::size_t, std::set<testing::ClosurePlace>> closure_at;
};

std::vector<Utterance> corpus() {
  const ArticulationModel& model = ArticulationModel::builtin();
  std::vector<Utterance> out;
  for (const auto& utterance : testing::load_closure_corpus(LIPSYNC_TEST_DATA_DIR, model)) {
    Utterance u{utterance.name, render_track(model, utterance.segments, {.fps = 30}), {}};
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

void run(const std::vector<Utterance>& utterances, const std::string& dump_path, const FaceSolverParams& params) {
  const int iterations = params.iterations;
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

// The file's number: festival_2.lab → 2 (the sentence; every voice and aligner has the same six).
int file_number(const std::string& name) {
  const std::string stem = std::filesystem::path(name).stem().string();
  return std::stoi(stem.substr(stem.rfind('_') + 1));
}

// A dump's frames split by file: displacements from rest, one column of 3 × soft nodes per frame.
struct SplitFrames {
  Eigen::MatrixXd fit, test;
  std::vector<bool> test_bilabial;  // per test column
};

SplitFrames read_split(const std::vector<Utterance>& utterances, const std::string& dump_path) {
  const FaceMesh& mesh = level1();
  const auto n = static_cast<Eigen::Index>(mesh.soft_node_count);
  Eigen::Index fit_count = 0, test_count = 0;
  for (const Utterance& u : utterances)
    (file_number(u.name) % 2 == 0 ? fit_count : test_count) += static_cast<Eigen::Index>(u.track.frame_count());
  SplitFrames out{Eigen::MatrixXd(3 * n, fit_count), Eigen::MatrixXd(3 * n, test_count), {}};
  std::ifstream dump(dump_path, std::ios::binary);
  if (!dump) throw std::runtime_error("cannot be read");
  std::vector<Vec3> x(mesh.soft_node_count);
  Eigen::Index fit_column = 0, test_column = 0;
  for (const Utterance& u : utterances) {
    const bool fit = file_number(u.name) % 2 == 0;
    for (std::size_t f = 0; f < u.track.frame_count(); ++f) {
      dump.read(reinterpret_cast<char*>(x.data()), static_cast<std::streamsize>(x.size() * sizeof(Vec3)));
      if (!dump) throw std::runtime_error("the dump is shorter than the corpus");
      auto column = fit ? out.fit.col(fit_column++) : out.test.col(test_column++);
      for (Eigen::Index i = 0; i < n; ++i) {
        const Vec3 rest = mesh.rest_positions_m[static_cast<std::size_t>(i)];
        const Vec3 p = x[static_cast<std::size_t>(i)];
        column.segment<3>(3 * i) = Eigen::Vector3d(p.x - rest.x, p.y - rest.y, p.z - rest.z);
      }
      if (!fit) out.test_bilabial.push_back(has(u, f, testing::ClosurePlace::bilabial));
    }
  }
  return out;
}

// The first k_max principal directions of the fit frames' displacements (not centred: a reduced
// model's pose is rest + U q, and rest is q = 0), orthonormal columns, through the frames' Gram
// matrix (frames × frames, smaller than 3n × 3n) and a QR that keeps the nested spans.
Eigen::MatrixXd principal_basis(const Eigen::MatrixXd& fit, Eigen::Index k_max, Eigen::VectorXd& variances) {
  const Eigen::MatrixXd gram = fit.transpose() * fit;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(gram);
  const Eigen::Index m = gram.rows();
  variances = eigen.eigenvalues().reverse();
  Eigen::MatrixXd basis(fit.rows(), k_max);
  for (Eigen::Index j = 0; j < k_max; ++j)
    basis.col(j) = fit * eigen.eigenvectors().col(m - 1 - j) / std::sqrt(std::max(variances(j), 1e-300));
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(basis);
  return qr.householderQ() * Eigen::MatrixXd::Identity(basis.rows(), k_max);
}

// Microseconds of the dense part of one reduced frame of dimension k (5 iterations, floats):
// x = U q for the springs and contacts, the reduced right-hand side Uᵀ r, and the two triangular
// solves with a k × k Cholesky factor made once. CPU time, the median of 7 batches.
double reduced_dense_us(const Eigen::MatrixXd& basis, Eigen::Index k, int iterations) {
  const Eigen::MatrixXf u = basis.leftCols(k).cast<float>();
  const Eigen::MatrixXf a = u.transpose() * u * 1e3F + Eigen::MatrixXf::Identity(k, k);  // any SPD matrix of the size
  const Eigen::LLT<Eigen::MatrixXf> llt(a);
  Eigen::VectorXf q = Eigen::VectorXf::Ones(k), x(u.rows()), r(k);
  const int frames = std::max(4, static_cast<int>(20000 / k));
  std::vector<double> batches;
  for (int batch = 0; batch < 7; ++batch) {
    const std::clock_t start = std::clock();  // CPU time, as face_bench reports
    for (int f = 0; f < frames; ++f)
      for (int it = 0; it < iterations; ++it) {
        x.noalias() = u * q;
        x.array() += 1e-6F;  // stands for the local step
        r.noalias() = u.transpose() * x;
        llt.solveInPlace(r);
        q = r;
      }
    batches.push_back(1e6 * static_cast<double>(std::clock() - start) / CLOCKS_PER_SEC / frames);
  }
  if (!q.allFinite()) std::fprintf(stderr, "not finite\n");
  std::nth_element(batches.begin(), batches.begin() + 3, batches.end());
  return batches[3];
}

void subspace(const std::vector<Utterance>& utterances, const std::string& dump_path, std::vector<Eigen::Index> ks) {
  const FaceMesh& mesh = level1();
  const auto n = static_cast<Eigen::Index>(mesh.soft_node_count);
  const SplitFrames frames = read_split(utterances, dump_path);
  const Eigen::Index k_max = std::min(*std::max_element(ks.begin(), ks.end()), frames.fit.cols());
  std::erase_if(ks, [&](Eigen::Index k) { return k > k_max; });
  Eigen::VectorXd variances;
  const Eigen::MatrixXd basis = principal_basis(frames.fit, k_max, variances);
  const Eigen::MatrixXd coordinates = basis.transpose() * frames.test;

  // Skin and lips (the nodes compare measures), and the lips among them.
  std::vector<Eigen::Index> measured, lips;
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto node = static_cast<std::size_t>(i);
    if (mesh.ring_depth[node] > 2.0) continue;
    measured.push_back(i);
    if (distance(mesh.rest_positions_m[node], mesh.mouth_centre_m) <= 0.015) lips.push_back(i);
  }
  const auto rows_of = [](const Eigen::MatrixXd& m, const std::vector<Eigen::Index>& nodes) {
    Eigen::MatrixXd out(3 * static_cast<Eigen::Index>(nodes.size()), m.cols());
    for (std::size_t j = 0; j < nodes.size(); ++j)
      out.middleRows<3>(3 * static_cast<Eigen::Index>(j)) = m.middleRows<3>(3 * nodes[j]);
    return out;
  };
  const Eigen::MatrixXd test_lips = rows_of(frames.test, lips);
  const Eigen::MatrixXd basis_lips = rows_of(basis, lips);

  std::vector<Vec3> pose(mesh.rest_positions_m);
  const auto gap_m = [&](const Eigen::MatrixXd& displacement, Eigen::Index column) {
    for (Eigen::Index i = 0; i < n; ++i) {
      const Vec3 rest = mesh.rest_positions_m[static_cast<std::size_t>(i)];
      pose[static_cast<std::size_t>(i)] = {rest.x + displacement(3 * i, column),
                                           rest.y + displacement(3 * i + 1, column),
                                           rest.z + displacement(3 * i + 2, column)};
    }
    return lip_gap_m(mesh, pose);
  };
  double reference_gap_m = 0;
  std::size_t keys = 0;
  for (Eigen::Index c = 0; c < frames.test.cols(); ++c)
    if (frames.test_bilabial[static_cast<std::size_t>(c)]) {
      reference_gap_m = std::max(reference_gap_m, gap_m(frames.test, c));
      ++keys;
    }
  const double total_variance = variances.sum();
  std::printf(
      "fit: %lld frames (files 2, 4, 6); test: %lld frames (files 1, 3, 5), %zu bilabial key frames, widest gap of "
      "the full solve there %.3f mm; %zu skin and lip nodes, %zu of them lips\n",
      static_cast<long long>(frames.fit.cols()), static_cast<long long>(frames.test.cols()), keys,
      1000 * reference_gap_m, measured.size(), lips.size());
  std::printf(
      "| k | fit variance kept | test: mean / worst node | beyond 0.3 mm | key frames: worst node | widest gap | "
      "floor on the worst node (lips): all / key frames | dense part, 5 iterations |\n");
  for (const Eigen::Index k : ks) {
    const Eigen::MatrixXd projected = basis.leftCols(k) * coordinates.topRows(k);
    double sum_m = 0, worst_m = 0, key_worst_m = 0, widest_gap_m = 0;
    Eigen::Index worst_node = 0;
    std::size_t count = 0, beyond = 0;
    for (Eigen::Index c = 0; c < frames.test.cols(); ++c) {
      const bool key = frames.test_bilabial[static_cast<std::size_t>(c)];
      for (const Eigen::Index i : measured) {
        const double d = (projected.col(c).segment<3>(3 * i) - frames.test.col(c).segment<3>(3 * i)).norm();
        sum_m += d;
        if (d > worst_m) {
          worst_m = d;
          worst_node = i;
        }
        if (key) key_worst_m = std::max(key_worst_m, d);
        ++count;
        if (d > 0.0003) ++beyond;
      }
      if (key) widest_gap_m = std::max(widest_gap_m, gap_m(projected, c));
    }
    // The floor: the least-squares fit on the lips alone, per frame; its root mean square per node.
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(basis_lips.leftCols(k));
    const Eigen::MatrixXd residual = test_lips - basis_lips.leftCols(k) * qr.solve(test_lips);
    double floor_m = 0, key_floor_m = 0;
    for (Eigen::Index c = 0; c < residual.cols(); ++c) {
      const double rms = std::sqrt(residual.col(c).squaredNorm() / static_cast<double>(lips.size()));
      floor_m = std::max(floor_m, rms);
      if (frames.test_bilabial[static_cast<std::size_t>(c)]) key_floor_m = std::max(key_floor_m, rms);
    }
    const auto worst = static_cast<std::size_t>(worst_node);
    std::printf(
        "| %lld | %.5f %% | %.4f / %.3f mm (ring %.1f, %.0f mm from the mouth centre) | %.3f %% | %.3f mm | "
        "%.3f mm | %.3f / %.3f mm | %.1f us |\n",
        static_cast<long long>(k), 100 * variances.head(k).sum() / total_variance,
        1000 * sum_m / static_cast<double>(count), 1000 * worst_m, mesh.ring_depth[worst],
        1000 * distance(mesh.rest_positions_m[worst], mesh.mouth_centre_m),
        100.0 * static_cast<double>(beyond) / static_cast<double>(count), 1000 * key_worst_m, 1000 * widest_gap_m,
        1000 * floor_m, 1000 * key_floor_m, reduced_dense_us(basis, k, FaceSolverParams{}.iterations));
  }
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.size() >= 2 && args.size() <= 3 && args[0] == "run") {
    FaceSolverParams params;
    if (args.size() == 3 && args[2] == "fast")
      params = lipsync::face::fast_face_solver_params();
    else if (args.size() == 3)
      params.iterations = std::stoi(args[2]);
    run(corpus(), args[1], params);
    return 0;
  }
  if (args.size() == 3 && args[0] == "compare") {
    compare(corpus(), args[1], args[2]);
    return 0;
  }
  if (args.size() >= 2 && args[0] == "subspace") {
    std::vector<Eigen::Index> ks;
    for (std::size_t a = 2; a < args.size(); ++a) ks.push_back(std::stoi(args[a]));
    if (ks.empty()) ks = {10, 20, 40, 80, 160, 320, 640, 1280};
    try {
      subspace(corpus(), args[1], ks);
    } catch (const std::runtime_error& e) {
      std::fprintf(stderr, "%s: %s\n", args[1].c_str(), e.what());
      return 1;
    }
    return 0;
  }
  std::fprintf(stderr,
               "usage: face_solver_study run DUMP [ITERATIONS | fast]\n"
               "       face_solver_study compare REFERENCE DUMP\n"
               "       face_solver_study subspace DUMP [K...]\n");
  return 2;
}
