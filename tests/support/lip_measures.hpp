// What a viewer measures on the simulated mouth, in metres: the gap between the lips across the
// middle of the mouth, the opening seen from the front, the lower lip's distance to the upper
// teeth, and how far the lips cross. Shared by the face tests and the server's mesh tests: each
// takes the mesh and one pose (all vertex positions in mesh order, as FaceSolver::positions() or a
// decoded mesh stream gives them).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_solver.hpp"

namespace lipsync::face {

inline double distance(Vec3 a, Vec3 b) { return std::hypot(a.x - b.x, a.y - b.y, a.z - b.z); }

inline double distance_to_segment(Vec3 p, Vec3 a, Vec3 b) {
  const Vec3 d{b.x - a.x, b.y - a.y, b.z - a.z};
  const double len2 = d.x * d.x + d.y * d.y + d.z * d.z;
  const double t =
      len2 > 0 ? std::clamp(((p.x - a.x) * d.x + (p.y - a.y) * d.y + (p.z - a.z) * d.z) / len2, 0.0, 1.0) : 0.0;
  return distance(p, {a.x + t * d.x, a.y + t * d.y, a.z + t * d.z});
}

/// Half-width of the middle of the mouth over which a seal is measured (the middle 20 mm).
inline constexpr double kSealHalfWidthM = 0.010;

// Largest distance from an upper-lip-line node within kSealHalfWidthM of the mouth's middle to the
// lower lip line (as a polyline through both corners): 0 when the lips are sealed there.
inline double lip_gap_m(const FaceMesh& mesh, std::span<const Vec3> x) {
  std::vector<std::uint32_t> lower{mesh.mouth_corners[0]};
  lower.insert(lower.end(), mesh.lower_lip_line.begin(), mesh.lower_lip_line.end());
  lower.push_back(mesh.mouth_corners[1]);
  double gap = 0;
  for (const auto u : mesh.upper_lip_line) {
    if (std::abs(mesh.rest_positions_m[u].x - mesh.mouth_centre_m.x) > kSealHalfWidthM) continue;
    double nearest = 1e9;
    for (std::size_t k = 1; k < lower.size(); ++k)
      nearest = std::min(nearest, distance_to_segment(x[u], x[lower[k - 1]], x[lower[k]]));
    gap = std::max(gap, nearest);
  }
  return gap;
}

// The mouth's opening seen from the front at the midline: the lowest upper-lip node minus the
// highest lower-lip node among skin and inner-lip nodes within 3 mm of the midline (at rest) and
// 20 mm of the mouth centre's height. Negative when the lips overlap (pressed or one in front).
inline double frontal_opening_m(const FaceMesh& mesh, std::span<const Vec3> x) {
  double upper = 1e9, lower = -1e9;
  for (std::uint32_t i = 0; i < mesh.soft_node_count; ++i) {
    const Vec3 r = mesh.rest_positions_m[i];
    if (mesh.ring_depth[i] > 2.0 || std::abs(r.x - mesh.mouth_centre_m.x) > 0.003 ||
        std::abs(r.y - mesh.mouth_centre_m.y) > 0.020)
      continue;
    if (mesh.jaw_weights[i] < 0.5)
      upper = std::min(upper, x[i].y);
    else
      lower = std::max(lower, x[i].y);
  }
  return upper - lower;
}

// Distance from p to the upper teeth's labial surface and incisal edge (skull frame).
inline double distance_to_upper_teeth_m(const FaceMesh& mesh, Vec3 p) {
  const double dy = p.y < mesh.upper_teeth_y_min_m   ? mesh.upper_teeth_y_min_m - p.y
                    : p.y > mesh.upper_teeth_y_max_m ? p.y - mesh.upper_teeth_y_max_m
                                                     : 0.0;
  const double u = p.x / mesh.upper_arch_a_m, w = (p.z - mesh.upper_arch_centre_z_m) / mesh.upper_arch_b_m;
  const double radius = std::hypot(u, w);
  // Radial distance to the ellipse, scaled back to metres by the local semi-axis.
  const double local_axis = std::hypot(u * mesh.upper_arch_a_m, w * mesh.upper_arch_b_m) / std::max(radius, 1e-9);
  return std::hypot(dy, std::abs(radius - 1.0) * local_axis);
}

inline double lower_lip_to_upper_teeth_m(const FaceMesh& mesh, std::span<const Vec3> x) {
  double nearest = 1e9;
  for (std::uint32_t i = 0; i < mesh.soft_node_count; ++i) {
    if (mesh.jaw_weights[i] < 0.99 || mesh.ring_depth[i] > 2.0) continue;
    if (distance(mesh.rest_positions_m[i], mesh.mouth_centre_m) > 0.015) continue;
    nearest = std::min(nearest, distance_to_upper_teeth_m(mesh, x[i]));
  }
  return nearest;
}

/// How far the lips cross: the largest amount by which an upper lip-line or inner-ring node lies
/// below its facing lower node (0 when none does).
inline double lip_crossing_m(const FaceMesh& mesh, std::span<const Vec3> x) {
  double crossing = 0;
  for (std::size_t k = 0; k < mesh.upper_lip_line.size(); ++k)
    crossing = std::max(crossing, x[mesh.lower_lip_line[k]].y - x[mesh.upper_lip_line[k]].y);
  for (std::size_t k = 0; k < mesh.upper_inner_ring.size(); ++k)
    crossing = std::max(crossing, x[mesh.lower_inner_ring[k]].y - x[mesh.upper_inner_ring[k]].y);
  return crossing;
}

inline double lip_gap_m(const FaceSolver& s) { return lip_gap_m(s.mesh(), s.positions()); }
inline double frontal_opening_m(const FaceSolver& s) { return frontal_opening_m(s.mesh(), s.positions()); }
inline double lower_lip_to_upper_teeth_m(const FaceSolver& s) {
  return lower_lip_to_upper_teeth_m(s.mesh(), s.positions());
}
inline double lip_crossing_m(const FaceSolver& s) { return lip_crossing_m(s.mesh(), s.positions()); }

}  // namespace lipsync::face
