// The local–global face solver; the model and its equations are in face_solver.hpp and
// docs/face.md. Layout: positions are n × 3 row-major doubles, every per-node array in the
// Cholesky factor's fill-reducing order (mesh order only in positions()). Each iteration forms the
// residual of the global system A_s x = b for the substep length s in double precision (diagonal
// part plus the spring projections, A is never stored) and solves for the correction with a
// single-precision supernodal copy of the factor of A_h (supernodal_factor.hpp: float values, one
// 16-bit row index per supernode row, x/y/z in one SSE vector): iterative refinement, so neither
// the float rounding nor s ≠ h moves the fixed point; they change how far one iteration gets, and
// for s < h the correction is relaxed by the optimal Richardson weight for the mismatch
// (docs/face.md, "The solver").
#include "lipsync/face/face_solver.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "face/arch.hpp"
#include "face/supernodal_factor.hpp"

namespace lipsync::face {

using detail::Float4;
using detail::SupernodalFactor;

namespace {

struct V3 {
  double x = 0, y = 0, z = 0;
  V3() = default;
  V3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
  V3(Vec3 v) : x(v.x), y(v.y), z(v.z) {}  // NOLINT(google-explicit-constructor)
  V3& operator+=(V3 o) {
    x += o.x;
    y += o.y;
    z += o.z;
    return *this;
  }
  V3& operator-=(V3 o) {
    x -= o.x;
    y -= o.y;
    z -= o.z;
    return *this;
  }
};
V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 operator*(double s, V3 a) { return {s * a.x, s * a.y, s * a.z}; }
double dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V3 cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double norm(V3 a) { return std::sqrt(dot(a, a)); }
V3 normalized(V3 a) {
  const double n = norm(a);
  return n > 0 ? (1.0 / n) * a : V3{};
}

double smoothstep(double edge0, double edge1, double x) {
  const double t = std::clamp((x - edge0) / (edge1 - edge0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Rotation about the x axis through `pivot` by `angle` (positive opens the jaw: points in front
// of the pivot move down).
struct XRotation {
  V3 pivot;
  double cos_a = 1, sin_a = 0;
  V3 apply(V3 p) const {
    const double y = p.y - pivot.y, z = p.z - pivot.z;
    return {p.x, pivot.y + cos_a * y - sin_a * z, pivot.z + sin_a * y + cos_a * z};
  }
  V3 apply_vector(V3 v) const { return {v.x, cos_a * v.y - sin_a * v.z, sin_a * v.y + cos_a * v.z}; }
  V3 inverse(V3 p) const {
    const double y = p.y - pivot.y, z = p.z - pivot.z;
    return {p.x, pivot.y + cos_a * y + sin_a * z, pivot.z - sin_a * y + cos_a * z};
  }
};
XRotation x_rotation(V3 pivot, double angle_rad) { return {pivot, std::cos(angle_rad), std::sin(angle_rad)}; }

bool push_out_of_arch(V3& p, double centre_z, double a, double b, double y_min, double y_max, double margin) {
  Vec3 q{p.x, p.y, p.z};
  if (!detail::push_out_of_arch(q, centre_z, a, b, y_min, y_max, margin)) return false;
  p = q;
  return true;
}

struct Spring {
  std::uint32_t i, j;
  double stiffness_n_per_m, rest_length_m;
  double stiffness_times_length_n;  // k · L, the projection's scale numerator
};

// A spring in the hot loop: its nodes and k · L (16 bytes; k is the same for all springs of a
// class, and the classes are stored one after the other).
struct HotSpring {
  std::uint32_t i, j;
  double stiffness_times_length_n;
};

struct Binding {
  std::uint32_t node;
  V3 displacement_m;  // per unit contraction, in the muscle's bone frame, times the binding share β
};

struct CompensatedNode {
  std::uint32_t node;
  double share;  // the node's jaw share J: how much of the jaw's motion it would follow
};

struct MuscleBindings {
  std::size_t channel;
  bool on_jaw;
  std::vector<Binding> bindings;          // displaced by c · displacement
  std::vector<Binding> closure_bindings;  // a sphincter's closure: by min(c, saturation) · displacement
  // A sphincter's protrusion: by max(c − saturation, 0) / (1 − saturation) · displacement, so that a
  // closing lip (c up to the saturation) meets the other without being pushed forward of it; by
  // c · displacement when the closure does not saturate (saturation 1).
  std::vector<Binding> protrusion_bindings;
  double closure_saturation = 1.0;
  // Lip–jaw compensation (rig.json "jaw_compensation"): each node gives back s · J of the jaw's
  // displacement of its rest position, s = share · smoothstep(from, full, c_driver).
  std::size_t compensation_channel = MuscleSpec::kNoChannel;
  double compensation_from = 0, compensation_full = 1, compensation_share = 0;
  std::vector<CompensatedNode> compensated;
};

// Closest point of a polyline: distance and arc-length parameter t ∈ [0, 1] (0 at the first point).
std::pair<double, double> closest_on_polyline(const std::vector<V3>& line, V3 p) {
  double total = 0;
  for (std::size_t k = 1; k < line.size(); ++k) total += norm(line[k] - line[k - 1]);
  double best = 1e300, best_t = 0, walked = 0;
  for (std::size_t k = 1; k < line.size(); ++k) {
    const V3 a = line[k - 1], d = line[k] - a;
    const double len2 = dot(d, d);
    const double s = len2 > 0 ? std::clamp(dot(p - a, d) / len2, 0.0, 1.0) : 0.0;
    const double dist = norm(p - (a + s * d));
    const double len = std::sqrt(len2);
    if (dist < best) {
      best = dist;
      best_t = total > 0 ? (walked + s * len) / total : 0.0;
    }
    walked += len;
  }
  return {best, best_t};
}

}  // namespace

struct FaceSolver::Impl {
  FaceMesh mesh;
  FaceRig rig;
  FaceSolverParams params;
  std::size_t n = 0;  // soft nodes

  std::vector<V3> rest, rest_normal;
  std::vector<double> mass_kg, attachment_n_per_m, jaw_share;
  std::vector<Spring> springs;
  std::vector<HotSpring> hot_springs;  // the same springs, internal indices
  std::size_t edge_spring_count = 0;   // springs [0, count) are skin edges, the rest bending
  std::vector<MuscleBindings> muscles;
  std::vector<std::uint8_t> teeth_contact, skull_contact;
  std::vector<double> sink_limit_m;
  SupernodalFactor factor;
  // Every per-node array above and the state below are in the factor's fill-reducing order:
  // mesh node i is internal node internal_index[i]. Springs, bindings and the lip pairs below hold
  // internal indices; only write_output() maps back to mesh order.
  std::vector<std::uint32_t> internal_index;
  std::vector<std::uint32_t> upper_lip_line, lower_lip_line, upper_inner_ring, lower_inner_ring;

  // State and per-step scratch (allocated once).
  std::vector<double> x, x_previous_step, velocity, y, target, inertia_and_attachment, residual;
  std::vector<double> last_substep_target;  // FaceSolverStart::targets_shift only
  std::vector<double> diagonal_n_per_m;     // M/s² + W per node for the substep length diagonal_step_s
  double diagonal_step_s = 0;
  float relaxation = 1;            // ω for substeps of diagonal_step_s
  double lowest_frequency_sq = 0;  // ω₀², rad²/s²: the smallest eigenvalue of (K + W) v = ω² M v
  std::vector<Float4> correction;
  std::vector<Vec3> output;
  XRotation jaw;
  XRotation skin_jaw;  // what the soft tissue follows: the jaw less the lip seal (FaceRig::skin_jaw_value)
  XRotation tongue;    // in the jaw's rest frame
  double tongue_protrusion_m = 0;

  Impl(const FaceMesh& mesh_, const FaceRig& rig_, const FaceSolverParams& params_)
      : mesh(mesh_), rig(rig_), params(params_), n(mesh_.soft_node_count) {
    if (params.iterations < 1 || !(params.time_step_s > 0) || !(params.skin_stiffness_n_per_m > 0) ||
        !(params.anchor_stiffness_n_per_m3 > 0) || params.bending_stiffness_n_per_m < 0 ||
        params.binding_stiffness_n_per_m3 < 0 || !(params.density_kg_per_m3 > 0) || !(params.damping_time_s > 0))
      throw std::invalid_argument(
          "FaceSolverParams: iterations ≥ 1 and positive time step, stiffness, density, damping");
    if (rig.channel_count() == 0) throw std::invalid_argument("FaceSolver: the rig has no channels");
    build_nodes();
    build_springs();
    build_bindings();
    build_collisions();
    factorize();
    reorder_nodes();
    x.assign(3 * n, 0.0);
    velocity.assign(3 * n, 0.0);
    y = x_previous_step = target = inertia_and_attachment = residual = x;
    if (params.start == FaceSolverStart::targets_shift) last_substep_target = x;
    correction.assign(n, Float4{0, 0, 0, 0});
    diagonal_n_per_m.resize(n);
    lowest_frequency_sq = estimate_lowest_frequency_sq();
    output.resize(mesh.vertex_count());
    reset();
  }

  void build_nodes() {
    rest.resize(n);
    for (std::size_t i = 0; i < n; ++i) rest[i] = mesh.rest_positions_m[i];
    rest_normal.assign(n, V3{});
    std::vector<double> area_m2(n, 0.0);
    for (const auto& t : mesh.triangles) {
      if (t[0] >= n || t[1] >= n || t[2] >= n) continue;
      const V3 c = cross(rest[t[1]] - rest[t[0]], rest[t[2]] - rest[t[0]]);
      const double area = 0.5 * norm(c);
      for (const auto v : t) {
        area_m2[v] += area / 3.0;
        rest_normal[v] += c;  // area-weighted
      }
    }
    for (auto& nrm : rest_normal) nrm = normalized(nrm);
    mass_kg.resize(n);
    attachment_n_per_m.resize(n);
    const V3 centre = mesh.mouth_centre_m;
    for (std::size_t i = 0; i < n; ++i) {
      mass_kg[i] = params.density_kg_per_m3 * params.tissue_thickness_m * area_m2[i];
      double scale =
          params.lip_anchor_scale + (1.0 - params.lip_anchor_scale) * smoothstep(0.015, 0.040, norm(rest[i] - centre));
      if (mesh.ring_depth[i] > 2.5) scale = params.cavity_anchor_scale;
      attachment_n_per_m[i] = params.anchor_stiffness_n_per_m3 * area_m2[i] * scale;
    }
    node_area_m2 = std::move(area_m2);
  }
  std::vector<double> node_area_m2;

  void build_springs() {
    // Edges, then a bending spring between the two far vertices of each interior edge.
    std::vector<std::pair<std::uint64_t, std::uint32_t>> half_edges;  // (sorted edge, opposite vertex)
    for (const auto& t : mesh.triangles) {
      if (t[0] >= n || t[1] >= n || t[2] >= n) continue;
      for (int e = 0; e < 3; ++e) {
        std::uint32_t a = t[static_cast<std::size_t>(e)], b = t[static_cast<std::size_t>((e + 1) % 3)];
        if (a > b) std::swap(a, b);
        half_edges.push_back({(std::uint64_t{a} << 32) | b, t[static_cast<std::size_t>((e + 2) % 3)]});
      }
    }
    std::sort(half_edges.begin(), half_edges.end());
    std::set<std::uint64_t> bend_pairs;
    for (std::size_t k = 0; k < half_edges.size();) {
      std::size_t end = k;
      while (end < half_edges.size() && half_edges[end].first == half_edges[k].first) ++end;
      const auto a = static_cast<std::uint32_t>(half_edges[k].first >> 32);
      const auto b = static_cast<std::uint32_t>(half_edges[k].first & 0xffffffffU);
      springs.push_back({a, b, params.skin_stiffness_n_per_m, norm(rest[a] - rest[b]), 0.0});
      if (end - k == 2 && params.bending_stiffness_n_per_m > 0) {
        std::uint32_t c = half_edges[k].second, d = half_edges[k + 1].second;
        if (c > d) std::swap(c, d);
        bend_pairs.insert((std::uint64_t{c} << 32) | d);
      }
      k = end;
    }
    edge_spring_count = springs.size();
    std::set<std::uint64_t> edge_set;
    for (const auto& s : springs) edge_set.insert((std::uint64_t{s.i} << 32) | s.j);
    for (const auto key : bend_pairs) {
      if (edge_set.count(key)) continue;
      const auto c = static_cast<std::uint32_t>(key >> 32), d = static_cast<std::uint32_t>(key & 0xffffffffU);
      springs.push_back({c, d, params.bending_stiffness_n_per_m, norm(rest[c] - rest[d]), 0.0});
    }
  }

  void build_bindings() {
    // Falloff weight w = (1 − (r/R)²)² within the fibre's radius R; binding stiffness
    // k_b = binding_stiffness · area · w. A node's attachment is the sum of its anchor and its
    // bindings, W = κ + Σ k_b, and its target is the W-weighted mean of the anchor's target and the
    // bound muscle points: target = B(rest) + Σ β_m (B_m(rest) − B(rest)) + Σ c_m β_m R_m D_m with
    // β_m = k_b / W. The bone part is folded into jaw_share; the muscle part is stored per muscle.
    const V3 centre = mesh.mouth_centre_m;
    std::vector<std::vector<std::pair<double, V3>>> per_muscle(rig.muscles().size(),
                                                               std::vector<std::pair<double, V3>>(n, {0.0, V3{}}));
    std::vector<std::vector<V3>> closure(rig.muscles().size(), std::vector<V3>(n, V3{}));
    std::vector<std::vector<V3>> protrusion(rig.muscles().size(), std::vector<V3>(n, V3{}));
    for (std::size_t m = 0; m < rig.muscles().size(); ++m) {
      const MuscleSpec& spec = rig.muscles()[m];
      const bool on_jaw = spec.bone == Bone::jaw;
      for (const FibreSpec& fibre : spec.fibres) {
        std::vector<V3> line;
        for (const auto id : fibre.path) line.push_back(mesh.rest_positions_m[id]);
        line.front().z -= spec.origin_depth_m;
        const V3 pull = normalized(line.front() - line.back());
        for (std::size_t i = 0; i < n; ++i) {
          if (mesh.ring_depth[i] > 2.5) continue;
          // Skin on the other bone's side of the mouth is not pulled (the upper lip is not bound
          // to a jaw muscle, the lower lip not to a skull muscle).
          if (on_jaw ? mesh.jaw_weights[i] < 0.4 : mesh.jaw_weights[i] > 0.6) continue;
          if (spec.kind == MuscleKind::sphincter && dot(rest[i] - centre, V3(spec.closure_direction)) > 0.001) continue;
          const auto [r, t] = closest_on_polyline(line, rest[i]);
          if (r >= fibre.radius_m) continue;
          const double q = r / fibre.radius_m;
          const double w = (1.0 - q * q) * (1.0 - q * q);
          if (w <= per_muscle[m][i].first) continue;
          V3 d;
          if (spec.kind == MuscleKind::linear) {
            const double ramp = smoothstep(spec.mobile_from, 1.0, t);
            d = (spec.max_shortening_m * ramp) * pull + (spec.bulge_m * 4.0 * t * (1.0 - t)) * rest_normal[i];
          } else {
            d = V3{spec.purse * (centre.x - rest[i].x), 0.0, 0.0};
            closure[m][i] = spec.closure_m * V3(spec.closure_direction);
            protrusion[m][i] = V3{0.0, 0.0, spec.protrusion_m} - spec.eversion_m * V3(spec.closure_direction);
          }
          per_muscle[m][i] = {w, d};
        }
      }
    }
    jaw_share =
        std::vector<double>(mesh.jaw_weights.begin(), mesh.jaw_weights.begin() + static_cast<std::ptrdiff_t>(n));
    std::vector<double> total(attachment_n_per_m);
    for (std::size_t m = 0; m < per_muscle.size(); ++m)
      for (std::size_t i = 0; i < n; ++i)
        total[i] += params.binding_stiffness_n_per_m3 * node_area_m2[i] * per_muscle[m][i].first;
    std::vector<double> bone_share_sum(n, 0.0), jaw_bound(n, 0.0);
    for (std::size_t m = 0; m < per_muscle.size(); ++m) {
      const MuscleSpec& spec = rig.muscles()[m];
      MuscleBindings mb{spec.channel,
                        spec.bone == Bone::jaw,
                        {},
                        {},
                        {},
                        spec.closure_saturation,
                        spec.compensation_channel,
                        spec.compensation_from,
                        spec.compensation_full,
                        spec.compensation_share,
                        {}};
      for (std::size_t i = 0; i < n; ++i) {
        if (per_muscle[m][i].first <= 0) continue;
        const double beta = params.binding_stiffness_n_per_m3 * node_area_m2[i] * per_muscle[m][i].first / total[i];
        bone_share_sum[i] += beta;
        if (mb.on_jaw) jaw_bound[i] += beta;
        mb.bindings.push_back({static_cast<std::uint32_t>(i), beta * per_muscle[m][i].second});
        if (spec.kind == MuscleKind::sphincter) {
          mb.closure_bindings.push_back({static_cast<std::uint32_t>(i), beta * closure[m][i]});
          mb.protrusion_bindings.push_back({static_cast<std::uint32_t>(i), beta * protrusion[m][i]});
        }
        if (mb.compensation_channel != MuscleSpec::kNoChannel)
          mb.compensated.push_back({static_cast<std::uint32_t>(i), 0.0});
      }
      muscles.push_back(std::move(mb));
    }
    for (std::size_t i = 0; i < n; ++i) jaw_share[i] = (1.0 - bone_share_sum[i]) * jaw_share[i] + jaw_bound[i];
    attachment_n_per_m = std::move(total);
    // A compensating lip holds its node's whole jaw-carried motion: the share is the node's jaw share.
    for (MuscleBindings& mb : muscles)
      for (CompensatedNode& node : mb.compensated) node.share = jaw_share[node.node];
  }

  void build_collisions() {
    const V3 centre = mesh.mouth_centre_m;
    teeth_contact.assign(n, 0);
    skull_contact.assign(n, 0);
    sink_limit_m.assign(n, params.max_skin_sink_m);
    for (std::size_t i = 0; i < n; ++i) {
      const double d = norm(rest[i] - centre);
      if (mesh.ring_depth[i] <= 2.5 && d < 0.035) {
        // Only skin that rests outside the teeth is kept there.
        V3 p = rest[i], q = rest[i];
        const bool inside =
            push_out_of_arch(p, mesh.upper_arch_centre_z_m, mesh.upper_arch_a_m, mesh.upper_arch_b_m,
                             mesh.upper_teeth_y_min_m, mesh.upper_teeth_y_max_m, params.teeth_margin_m) ||
            push_out_of_arch(q, mesh.lower_arch_centre_z_m, mesh.lower_arch_a_m, mesh.lower_arch_b_m,
                             mesh.lower_teeth_y_min_m, mesh.lower_teeth_y_max_m, params.teeth_margin_m);
        teeth_contact[i] = inside ? 0 : 1;
      }
      if (mesh.ring_depth[i] == 0.0) {
        skull_contact[i] = 1;
        if (d < 0.030) sink_limit_m[i] = 0.015;  // lips and the mouth's surround are thick and soft
      }
    }
  }

  void factorize() {
    // A = M/h² + Σ k (e_i − e_j)(e_i − e_j)ᵀ + diag(W), one n × n matrix for x, y and z.
    const double inv_h2 = 1.0 / (params.time_step_s * params.time_step_s);
    std::vector<Eigen::Triplet<double>> entries;
    entries.reserve(n + 4 * springs.size());
    for (std::size_t i = 0; i < n; ++i) {
      const auto ii = static_cast<int>(i);
      entries.emplace_back(ii, ii, mass_kg[i] * inv_h2 + attachment_n_per_m[i]);
    }
    for (const Spring& s : springs) {
      const auto i = static_cast<int>(s.i), j = static_cast<int>(s.j);
      entries.emplace_back(i, i, s.stiffness_n_per_m);
      entries.emplace_back(j, j, s.stiffness_n_per_m);
      entries.emplace_back(i, j, -s.stiffness_n_per_m);
      entries.emplace_back(j, i, -s.stiffness_n_per_m);
    }
    Eigen::SparseMatrix<double> a(static_cast<Eigen::Index>(n), static_cast<Eigen::Index>(n));
    a.setFromTriplets(entries.begin(), entries.end());
    Eigen::SimplicialLLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>> llt(a);
    if (llt.info() != Eigen::Success)
      throw std::invalid_argument("FaceSolver: the system matrix is not positive definite");
    // L in compressed columns (diagonal first), converted to the single-precision factor.
    const Eigen::SparseMatrix<double> l = llt.matrixL();
    const int* outer = l.outerIndexPtr();
    const int* inner = l.innerIndexPtr();
    const double* value = l.valuePtr();
    factor.build(n, outer, inner, value);
    const auto& indices = llt.permutationP().indices();
    internal_index.assign(indices.data(), indices.data() + indices.size());
  }

  // Puts every per-node array, spring, binding and lip pair into the factor's order.
  void reorder_nodes() {
    auto permute = [&](auto& values) {
      auto reordered = values;
      for (std::size_t i = 0; i < n; ++i) reordered[internal_index[i]] = values[i];
      values = std::move(reordered);
    };
    permute(rest);
    permute(rest_normal);
    permute(mass_kg);
    permute(attachment_n_per_m);
    permute(jaw_share);
    permute(teeth_contact);
    permute(skull_contact);
    permute(sink_limit_m);
    permute(node_area_m2);
    for (Spring& s : springs) {
      s.i = internal_index[s.i];
      s.j = internal_index[s.j];
      s.stiffness_times_length_n = s.stiffness_n_per_m * s.rest_length_m;
      hot_springs.push_back({s.i, s.j, s.stiffness_times_length_n});
    }

    for (MuscleBindings& mb : muscles) {
      for (Binding& b : mb.bindings) b.node = internal_index[b.node];
      for (Binding& b : mb.closure_bindings) b.node = internal_index[b.node];
      for (Binding& b : mb.protrusion_bindings) b.node = internal_index[b.node];
      for (CompensatedNode& c : mb.compensated) c.node = internal_index[c.node];
    }
    auto mapped = [&](const std::vector<std::uint32_t>& ids) {
      std::vector<std::uint32_t> out;
      out.reserve(ids.size());
      for (const auto id : ids) out.push_back(internal_index[id]);
      return out;
    };
    upper_lip_line = mapped(mesh.upper_lip_line);
    lower_lip_line = mapped(mesh.lower_lip_line);
    upper_inner_ring = mapped(mesh.upper_inner_ring);
    lower_inner_ring = mapped(mesh.lower_inner_ring);
  }

  // ω₀² from the largest eigenvalue μ of A_h⁻¹ M (= 1/(ω₀² + 1/h²)): power iteration in the
  // M inner product, in which A_h⁻¹ M is self-adjoint, so the Rayleigh quotient rises toward μ.
  // Three start vectors (uniform, and the rest x and y coordinates: the smooth shapes the lowest
  // mode resembles) in the three lanes of one solve. An underestimate of μ only makes the
  // relaxation less cautious: ω = 2/(1 + λ_estimated) stays convergent while the true
  // λ(s) < 1 + λ_estimated. 40 iterations agree with 400 to six digits (482 rad/s at every level).
  double estimate_lowest_frequency_sq() {
    std::vector<Float4> v(n), w(n);
    for (std::size_t i = 0; i < n; ++i)
      v[i] = Float4{1.0F, static_cast<float>(rest[i].x), static_cast<float>(rest[i].y), 0.0F};
    double mu = 0;
    for (int iteration = 0; iteration < 40; ++iteration) {
      for (std::size_t i = 0; i < n; ++i) w[i] = static_cast<float>(mass_kg[i]) * v[i];
      factor.solve_in_place(w.data());
      std::array<double, 3> vmw{}, vmv{}, wmw{};
      for (std::size_t i = 0; i < n; ++i)
        for (std::size_t c = 0; c < 3; ++c) {
          vmw[c] += mass_kg[i] * static_cast<double>(v[i][c]) * static_cast<double>(w[i][c]);
          vmv[c] += mass_kg[i] * static_cast<double>(v[i][c]) * static_cast<double>(v[i][c]);
          wmw[c] += mass_kg[i] * static_cast<double>(w[i][c]) * static_cast<double>(w[i][c]);
        }
      for (std::size_t c = 0; c < 3; ++c) {
        if (vmv[c] > 0) mu = std::max(mu, vmw[c] / vmv[c]);
        const auto scale = static_cast<float>(wmw[c] > 0 ? 1.0 / std::sqrt(wmw[c]) : 0.0);
        for (std::size_t i = 0; i < n; ++i) v[i][c] = w[i][c] * scale;
      }
    }
    const double inv_h2 = 1.0 / (params.time_step_s * params.time_step_s);
    return mu > 0 ? std::max(1.0 / mu - inv_h2, 0.0) : 0.0;
  }

  void reset() {
    for (std::size_t i = 0; i < n; ++i) {
      x[3 * i] = rest[i].x;
      x[3 * i + 1] = rest[i].y;
      x[3 * i + 2] = rest[i].z;
    }
    std::fill(velocity.begin(), velocity.end(), 0.0);
    x_previous_step = x;
    target = x;
    if (params.start == FaceSolverStart::targets_shift) last_substep_target = target;
    jaw = skin_jaw = x_rotation(mesh.anatomy.jaw_hinge_m, 0.0);
    tongue = x_rotation(mesh.tongue_root_m, 0.0);
    tongue_protrusion_m = 0.0;
    write_output();
  }

  double channel(std::span<const float> values, std::size_t index, double lo, double hi) const {
    if (index >= values.size()) return 0.0;
    const double v = static_cast<double>(values[index]);
    return std::isfinite(v) ? std::clamp(v, lo, hi) : 0.0;
  }

  void compute_targets(std::span<const float> values) {
    const double jaw_value = channel(values, rig.jaw_channel(), 0.0, 1.0);
    jaw = x_rotation(mesh.anatomy.jaw_hinge_m, jaw_value * rig.max_jaw_rotation_rad());
    skin_jaw = x_rotation(mesh.anatomy.jaw_hinge_m, rig.skin_jaw_value(jaw_value) * rig.max_jaw_rotation_rad());
    tongue = x_rotation(mesh.tongue_root_m,
                        -channel(values, rig.tongue_raise_channel(), -1.0, 1.0) * rig.max_tongue_raise_rad());
    tongue_protrusion_m = channel(values, rig.tongue_protrusion_channel(), 0.0, 1.0) * rig.max_tongue_protrusion_m();
    for (std::size_t i = 0; i < n; ++i) {
      const V3 carried = rest[i] + jaw_share[i] * (skin_jaw.apply(rest[i]) - rest[i]);
      target[3 * i] = carried.x;
      target[3 * i + 1] = carried.y;
      target[3 * i + 2] = carried.z;
    }
    for (const MuscleBindings& mb : muscles) {
      if (!mb.compensated.empty()) {
        // The lip holds s of its jaw-closed position: minus s · J of the jaw's displacement.
        const double s = mb.compensation_share * smoothstep(mb.compensation_from, mb.compensation_full,
                                                            channel(values, mb.compensation_channel, 0.0, 1.0));
        if (s > 0.0) {
          for (const CompensatedNode& node : mb.compensated) {
            const V3 drop = skin_jaw.apply(rest[node.node]) - rest[node.node];
            target[3 * node.node] -= s * node.share * drop.x;
            target[3 * node.node + 1] -= s * node.share * drop.y;
            target[3 * node.node + 2] -= s * node.share * drop.z;
          }
        }
      }
      const double c = channel(values, mb.channel, 0.0, 1.0);
      if (c == 0.0) continue;
      const auto displace = [&](const std::vector<Binding>& bindings, double scale) {
        for (const Binding& b : bindings) {
          const V3 d = mb.on_jaw ? skin_jaw.apply_vector(scale * b.displacement_m) : scale * b.displacement_m;
          target[3 * b.node] += d.x;
          target[3 * b.node + 1] += d.y;
          target[3 * b.node + 2] += d.z;
        }
      };
      displace(mb.bindings, c);
      displace(mb.closure_bindings, std::min(c, mb.closure_saturation));
      if (mb.closure_saturation >= 1.0)
        displace(mb.protrusion_bindings, c);
      else if (c > mb.closure_saturation)
        displace(mb.protrusion_bindings, (c - mb.closure_saturation) / (1.0 - mb.closure_saturation));
    }
  }

  // One implicit-Euler step of length `s` ≤ h, the factor's step. The residual uses the exact
  // mass term M/s², the factor A_h's: for s < h the preconditioned system A_h⁻¹ A_s has
  // eigenvalues in [1, λ(s)], λ(s) = (ω₀² + 1/s²)/(ω₀² + 1/h²) at the face's lowest natural
  // frequency ω₀ (stiffer modes are closer to 1), so the correction is relaxed by
  // ω = 2/(1 + λ(s)), the optimal Richardson weight on that interval (ω = 1 for s = h).
  void substep(double s) {
    const double inv_s2 = 1.0 / (s * s);
    if (s != diagonal_step_s) {
      for (std::size_t i = 0; i < n; ++i) diagonal_n_per_m[i] = mass_kg[i] * inv_s2 + attachment_n_per_m[i];
      const double inv_h2 = 1.0 / (params.time_step_s * params.time_step_s);
      const double lambda = (lowest_frequency_sq + inv_s2) / (lowest_frequency_sq + inv_h2);
      relaxation = static_cast<float>(2.0 / (1.0 + std::max(lambda, 1.0)));
      diagonal_step_s = s;
    }
    const double decay = std::exp(-s / params.damping_time_s);
    for (std::size_t k = 0; k < 3 * n; ++k) y[k] = x[k] + s * decay * velocity[k];
    x_previous_step = x;
    x = y;
    if (params.start == FaceSolverStart::targets_shift) {
      for (std::size_t k = 0; k < 3 * n; ++k) {
        x[k] += target[k] - last_substep_target[k];
        last_substep_target[k] = target[k];
      }
    }
    for (std::size_t i = 0; i < n; ++i) {
      const double m = mass_kg[i] * inv_s2, w = attachment_n_per_m[i];
      for (std::size_t c = 0; c < 3; ++c) inertia_and_attachment[3 * i + c] = m * y[3 * i + c] + w * target[3 * i + c];
    }
    // Each iteration solves A x' = M y/s² + W target + Σ k Sᵀ p for the correction x' − x, from the
    // residual r = (M y/s² + W target + Σ k Sᵀ p) − A x in double precision: the diagonal part
    // (M/s² + W) x, and per spring k Sᵀ (p − S x) = (k L/|d| − k) d with d = x_i − x_j.
    for (int iteration = 0; iteration < params.iterations; ++iteration) {
      for (std::size_t k = 0; k < 3 * n; ++k) residual[k] = inertia_and_attachment[k] - diagonal_n_per_m[k / 3] * x[k];
      add_spring_residuals(0, edge_spring_count, params.skin_stiffness_n_per_m);
      add_spring_residuals(edge_spring_count, hot_springs.size(), params.bending_stiffness_n_per_m);
      for (std::size_t i = 0; i < n; ++i)
        correction[i] = Float4{static_cast<float>(residual[3 * i]), static_cast<float>(residual[3 * i + 1]),
                               static_cast<float>(residual[3 * i + 2]), 0.0F};
      factor.solve_in_place(correction.data());
      for (std::size_t i = 0; i < n; ++i) {
        const Float4 d = relaxation * correction[i];
        x[3 * i] += static_cast<double>(d[0]);
        x[3 * i + 1] += static_cast<double>(d[1]);
        x[3 * i + 2] += static_cast<double>(d[2]);
      }
      // The lip–lip contact is a constraint of every iteration: its projection is where the
      // next iteration's springs start from, so the lips deform around the contact.
      resolve_lip_contact();
    }
    resolve_contacts();
    const double inv_s = 1.0 / s;
    for (std::size_t k = 0; k < 3 * n; ++k) velocity[k] = (x[k] - x_previous_step[k]) * inv_s;
  }

  // Springs two at a time: their square roots and divisions share one SSE2 instruction each
  // (correctly rounded, so the results are the scalar loop's, bit for bit).
  void add_spring_residuals(std::size_t begin, std::size_t end, double stiffness_n_per_m) {
    double* r = residual.data();
    const double* p = x.data();
    const auto add = [&](const HotSpring& s, double dx, double dy, double dz, double scale) {
      r[3 * s.i] += scale * dx;
      r[3 * s.i + 1] += scale * dy;
      r[3 * s.i + 2] += scale * dz;
      r[3 * s.j] -= scale * dx;
      r[3 * s.j + 1] -= scale * dy;
      r[3 * s.j + 2] -= scale * dz;
    };
    std::size_t k = begin;
#if defined(__SSE2__)
    const __m128d tiny = _mm_set1_pd(1e-12), stiffness = _mm_set1_pd(stiffness_n_per_m);
    for (; k + 2 <= end; k += 2) {
      const HotSpring a = hot_springs[k], b = hot_springs[k + 1];
      const double ax = p[3 * a.i] - p[3 * a.j], ay = p[3 * a.i + 1] - p[3 * a.j + 1],
                   az = p[3 * a.i + 2] - p[3 * a.j + 2];
      const double bx = p[3 * b.i] - p[3 * b.j], by = p[3 * b.i + 1] - p[3 * b.j + 1],
                   bz = p[3 * b.i + 2] - p[3 * b.j + 2];
      const __m128d length = _mm_sqrt_pd(_mm_set_pd(bx * bx + by * by + bz * bz, ax * ax + ay * ay + az * az));
      const __m128d ratio =
          _mm_and_pd(_mm_cmpgt_pd(length, tiny),
                     _mm_div_pd(_mm_set_pd(b.stiffness_times_length_n, a.stiffness_times_length_n), length));
      alignas(16) double scale[2];
      _mm_store_pd(scale, _mm_sub_pd(ratio, stiffness));
      add(a, ax, ay, az, scale[0]);
      add(b, bx, by, bz, scale[1]);
    }
#endif
    for (; k < end; ++k) {
      const HotSpring s = hot_springs[k];
      const double dx = p[3 * s.i] - p[3 * s.j], dy = p[3 * s.i + 1] - p[3 * s.j + 1],
                   dz = p[3 * s.i + 2] - p[3 * s.j + 2];
      const double length = std::sqrt(dx * dx + dy * dy + dz * dz);
      add(s, dx, dy, dz, (length > 1e-12 ? s.stiffness_times_length_n / length : 0.0) - stiffness_n_per_m);
    }
  }

  V3 node(std::size_t i) const { return {x[3 * i], x[3 * i + 1], x[3 * i + 2]}; }
  void set_node(std::size_t i, V3 p) {
    x[3 * i] = p.x;
    x[3 * i + 1] = p.y;
    x[3 * i + 2] = p.z;
  }

  // Lip–lip contact: a facing upper/lower pair (lip line and inner ring) may touch but not cross.
  // Lips pressed together (the upper node at or below the lower one) meet face to face: the pair is
  // projected onto its mass-weighted meeting point in height and depth, and each node keeps its
  // sideways position (the lips slide along each other, no zipper pulls the corners in). Run after every local–global
  // iteration, so that the next iteration's springs start from the projection and the lips deform
  // around the contact, and once more at the end of the step, so that no step ends crossed.
  void resolve_lip_contact() {
    auto press = [&](const std::vector<std::uint32_t>& upper, const std::vector<std::uint32_t>& lower) {
      for (std::size_t k = 0; k < upper.size() && k < lower.size(); ++k) {
        const std::size_t u = upper[k], l = lower[k];
        if (x[3 * u + 1] > x[3 * l + 1]) continue;
        const double upper_share = mass_kg[l] / (mass_kg[u] + mass_kg[l]);
        for (const std::size_t c : {1U, 2U}) {
          const double d = x[3 * l + c] - x[3 * u + c];
          x[3 * u + c] += upper_share * d;
          x[3 * l + c] -= (1.0 - upper_share) * d;
        }
      }
    };
    press(upper_lip_line, lower_lip_line);
    press(upper_inner_ring, lower_inner_ring);
  }

  // Teeth and skull keep the skin outside; the lip contact comes last, so no step ends crossed.
  void resolve_contacts() {
    const double margin = params.teeth_margin_m;
    for (std::size_t i = 0; i < n; ++i) {
      if (teeth_contact[i]) {
        V3 p = node(i);
        bool moved = push_out_of_arch(p, mesh.upper_arch_centre_z_m, mesh.upper_arch_a_m, mesh.upper_arch_b_m,
                                      mesh.upper_teeth_y_min_m, mesh.upper_teeth_y_max_m, margin);
        V3 q = jaw.inverse(p);
        if (push_out_of_arch(q, mesh.lower_arch_centre_z_m, mesh.lower_arch_a_m, mesh.lower_arch_b_m,
                             mesh.lower_teeth_y_min_m, mesh.lower_teeth_y_max_m, margin)) {
          p = jaw.apply(q);
          moved = true;
        }
        if (moved) set_node(i, p);
      }
      if (skull_contact[i]) {
        // Half-space under the skin: the node's rest position carried by its bones, minus the
        // allowed sink along the carried rest normal.
        const V3 carried = rest[i] + jaw_share[i] * (skin_jaw.apply(rest[i]) - rest[i]);
        const V3 normal =
            normalized(rest_normal[i] + jaw_share[i] * (skin_jaw.apply_vector(rest_normal[i]) - rest_normal[i]));
        const V3 p = node(i);
        const double depth = dot(p - carried, normal) + sink_limit_m[i];
        if (depth < 0) set_node(i, p - depth * normal);
      }
    }
    resolve_lip_contact();
  }

  void write_output() {
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t k = internal_index[i];
      output[i] = {x[3 * k], x[3 * k + 1], x[3 * k + 2]};
    }
    for (std::size_t i = mesh.upper_teeth_begin; i < mesh.lower_teeth_begin; ++i) output[i] = mesh.rest_positions_m[i];
    for (std::size_t i = mesh.lower_teeth_begin; i < mesh.tongue_begin; ++i) {
      const V3 p = jaw.apply(mesh.rest_positions_m[i]);
      output[i] = {p.x, p.y, p.z};
    }
    for (std::size_t i = mesh.tongue_begin; i < mesh.eyes_begin; ++i) {
      V3 p = tongue.apply(mesh.rest_positions_m[i]);
      p.z += tongue_protrusion_m;
      p = jaw.apply(p);
      output[i] = {p.x, p.y, p.z};
    }
    for (std::size_t i = mesh.eyes_begin; i < mesh.vertex_count(); ++i) output[i] = mesh.rest_positions_m[i];
  }

  double energy() const {
    double e = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const V3 v{velocity[3 * i], velocity[3 * i + 1], velocity[3 * i + 2]};
      const V3 d = node(i) - V3{target[3 * i], target[3 * i + 1], target[3 * i + 2]};
      e += 0.5 * mass_kg[i] * dot(v, v) + 0.5 * attachment_n_per_m[i] * dot(d, d);
    }
    for (const Spring& s : springs) {
      const double stretch = norm(node(s.i) - node(s.j)) - s.rest_length_m;
      e += 0.5 * s.stiffness_n_per_m * stretch * stretch;
    }
    return e;
  }
};

FaceSolverParams fast_face_solver_params() {
  FaceSolverParams params;
  params.iterations = 2;
  params.start = FaceSolverStart::targets_shift;
  return params;
}

FaceSolver::FaceSolver(const FaceMesh& mesh, const FaceRig& rig, const FaceSolverParams& params)
    : impl_(std::make_unique<Impl>(mesh, rig, params)) {}
FaceSolver::~FaceSolver() = default;
FaceSolver::FaceSolver(FaceSolver&&) noexcept = default;
FaceSolver& FaceSolver::operator=(FaceSolver&&) noexcept = default;

void FaceSolver::step(std::span<const float> channel_values, double dt_s) {
  impl_->compute_targets(channel_values);
  if (std::isfinite(dt_s) && dt_s > 0) {
    // Equal substeps of at most 1.01 h (a 30 frames/s grid in whole microseconds has intervals
    // of 33,334 µs: still one substep), at most 1000, so the simulated time is exactly dt.
    const double h = impl_->params.time_step_s;
    const double count = std::ceil(dt_s / (1.01 * h));
    const int substeps = std::clamp(static_cast<int>(std::min(count, 1000.0)), 1, 1000);
    const double s = dt_s / substeps;
    for (int k = 0; k < substeps; ++k) impl_->substep(s);
  }
  impl_->write_output();
}

void FaceSolver::reset() { impl_->reset(); }
std::span<const Vec3> FaceSolver::positions() const { return impl_->output; }
const FaceMesh& FaceSolver::mesh() const { return impl_->mesh; }
double FaceSolver::energy_j() const { return impl_->energy(); }
std::size_t FaceSolver::spring_count() const { return impl_->springs.size(); }
std::size_t FaceSolver::binding_count() const {
  std::size_t count = 0;
  for (const auto& m : impl_->muscles) count += m.bindings.size();
  return count;
}

}  // namespace lipsync::face
