// Builds the simulated face from the canonical mesh; see face_mesh.hpp for the layout and
// docs/face.md for the anatomy and its figures. build_face_mesh() runs one step per helper, in
// this order: open the mouth (open_mouth, order_lip_loop), bring the lips together for the rest
// pose (close_lips_at_rest: the asset's lips are 5.5 mm apart), close it off behind the lips with the
// inner-lip and cavity rings (add_mouth_cavity), subdivide with the lip lines refined as polylines
// (subdivide_soft_nodes), weight the soft nodes between skull and jaw (assign_jaw_weights), then
// add the rigid parts: the teeth arches, with the inner lips pushed outside them (add_teeth), and
// the tongue (add_tongue).
#include "lipsync/face/face_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <string>
#include <unordered_map>

#include "face/arch.hpp"
#include "face/embedded_face.hpp"
#include "lipsync/error.hpp"
#include "lipsync/setting_ranges.hpp"

namespace lipsync::face {

const std::array<std::array<std::uint32_t, 16>, 2> kEyeContours = {{
    {33, 246, 161, 160, 159, 158, 157, 173, 133, 155, 154, 153, 145, 144, 163, 7},
    {263, 466, 388, 387, 386, 385, 384, 398, 362, 382, 381, 380, 374, 373, 390, 249},
}};

const std::array<std::uint32_t, 20> kInnerLipLoop = {78,  191, 80,  81,  82,  13, 312, 311, 310, 415,
                                                     308, 324, 318, 402, 317, 14, 87,  178, 88,  95};

namespace {

constexpr double kMetresPerCentimetre = 0.01;
constexpr std::size_t kLoopSize = kInnerLipLoop.size();
constexpr std::size_t kUpperBegin = 1, kUpperEnd = 10;   // loop indices of the upper interior
constexpr std::size_t kLowerBegin = 11, kLowerEnd = 20;  // lower interior (308 → 78 order)

Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec3 operator*(double s, Vec3 a) { return {s * a.x, s * a.y, s * a.z}; }

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t{a} << 32) | b;
}

double smoothstep(double edge0, double edge1, double x) {
  const double t = std::clamp((x - edge0) / (edge1 - edge0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Adds a rigid teeth arch: front and back elliptic bands between y_min and y_max, over ±80°
// around the front, with the incisal and gum edges closed. Returns nothing; appends vertices.
void add_arch(FaceMesh& mesh, double centre_z, double a, double b, double thickness, double y_min, double y_max,
              FacePart part) {
  constexpr int kSegments = 16;
  constexpr double kHalfAngle = 80.0 * std::numbers::pi / 180.0;
  const auto base = static_cast<std::uint32_t>(mesh.rest_positions_m.size());
  for (int s = 0; s <= kSegments; ++s) {
    const double angle = -kHalfAngle + 2.0 * kHalfAngle * s / kSegments;
    for (const double shrink : {0.0, thickness}) {
      for (const double y : {y_min, y_max}) {
        mesh.rest_positions_m.push_back({(a - shrink) * std::sin(angle), y, centre_z + (b - shrink) * std::cos(angle)});
        mesh.uvs.push_back({0.0F, 0.0F});
        mesh.parts.push_back(part);
      }
    }
  }
  // Vertex (s, layer, row) = base + 4 s + 2 layer + row; layer 0 front, 1 back; row 0 bottom, 1 top.
  auto v = [&](int s, int layer, int row) { return base + static_cast<std::uint32_t>(4 * s + 2 * layer + row); };
  for (int s = 0; s < kSegments; ++s) {
    auto quad = [&](std::uint32_t p, std::uint32_t q, std::uint32_t r, std::uint32_t t) {
      mesh.triangles.push_back({p, q, r});
      mesh.triangles.push_back({p, r, t});
    };
    quad(v(s, 0, 0), v(s + 1, 0, 0), v(s + 1, 0, 1), v(s, 0, 1));  // labial face, seen from the front
    quad(v(s + 1, 1, 0), v(s, 1, 0), v(s, 1, 1), v(s + 1, 1, 1));  // lingual face
    quad(v(s, 1, 0), v(s + 1, 1, 0), v(s + 1, 0, 0), v(s, 0, 0));  // bottom edge
    quad(v(s, 0, 1), v(s + 1, 0, 1), v(s + 1, 1, 1), v(s, 1, 1));  // top edge
  }
}

void add_tongue(FaceMesh& mesh) {
  constexpr int kRings = 8, kSectors = 12;
  const Vec3 c = mesh.tongue_centre_m;
  const Vec3 r = mesh.anatomy.tongue_semi_axes_m;
  const auto base = static_cast<std::uint32_t>(mesh.rest_positions_m.size());
  // Pole along +z (the tip) and −z (the root); rings in between.
  auto push = [&](Vec3 p) {
    mesh.rest_positions_m.push_back(p);
    mesh.uvs.push_back({0.0F, 0.0F});
    mesh.parts.push_back(FacePart::tongue);
  };
  push({c.x, c.y, c.z + r.z});
  for (int i = 1; i < kRings; ++i) {
    const double polar = std::numbers::pi * i / kRings;
    for (int j = 0; j < kSectors; ++j) {
      const double azimuth = 2.0 * std::numbers::pi * j / kSectors;
      push({c.x + r.x * std::sin(polar) * std::cos(azimuth), c.y + r.y * std::sin(polar) * std::sin(azimuth),
            c.z + r.z * std::cos(polar)});
    }
  }
  push({c.x, c.y, c.z - r.z});
  const std::uint32_t tip = base, back = base + 1 + (kRings - 1) * kSectors;
  auto ring = [&](int i, int j) { return base + 1 + static_cast<std::uint32_t>((i - 1) * kSectors + (j % kSectors)); };
  for (int j = 0; j < kSectors; ++j) {
    mesh.triangles.push_back({tip, ring(1, j + 1), ring(1, j)});
    for (int i = 1; i < kRings - 1; ++i) {
      mesh.triangles.push_back({ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)});
      mesh.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)});
    }
    mesh.triangles.push_back({back, ring(kRings - 1, j), ring(kRings - 1, j + 1)});
  }
}

using LoopRing = std::array<std::uint32_t, kLoopSize>;

// The soft nodes while they are built: per-vertex arrays that grow together, and the triangles.
struct SoftNodes {
  std::vector<Vec3> pos;
  std::vector<std::array<double, 2>> uv;
  std::vector<double> depth;  // rings behind the lip line (FaceMesh::ring_depth)
  std::vector<double> side;   // +1 upper lip, −1 lower lip, 0 elsewhere; blended at midpoints
  // How far close_lips_at_rest moved the node (metres; the asset's position is pos − shift).
  std::vector<Vec3> shift;
  std::vector<std::array<std::uint32_t, 3>> tris;

  std::uint32_t add(Vec3 p, std::array<double, 2> t, double d, double s, Vec3 moved = {}) {
    const auto id = static_cast<std::uint32_t>(pos.size());
    pos.push_back(p);
    uv.push_back(t);
    depth.push_back(d);
    side.push_back(s);
    shift.push_back(moved);
    return id;
  }
};

// The asset in metres with the mouth and the eyes opened: every triangle whose three vertices lie
// on the inner-lip loop, or on one eye's contour, is dropped.
SoftNodes open_mouth(const FaceAsset& asset) {
  SoftNodes nodes;
  nodes.uv = asset.uvs;
  for (const auto& p : asset.positions_cm) nodes.pos.push_back(kMetresPerCentimetre * p);
  nodes.depth.assign(nodes.pos.size(), 0.0);
  nodes.side.assign(nodes.pos.size(), 0.0);
  nodes.shift.assign(nodes.pos.size(), Vec3{});
  std::vector<bool> on_loop(nodes.pos.size(), false);
  for (const auto id : kInnerLipLoop) on_loop.at(id) = true;
  std::vector<int> on_eye(nodes.pos.size(), -1);
  for (int eye = 0; eye < 2; ++eye)
    for (const auto id : kEyeContours[static_cast<std::size_t>(eye)]) on_eye.at(id) = eye;
  for (const auto& t : asset.triangles) {
    const bool mouth_fill = on_loop[t[0]] && on_loop[t[1]] && on_loop[t[2]];
    const bool eye_fill = on_eye[t[0]] >= 0 && on_eye[t[0]] == on_eye[t[1]] && on_eye[t[0]] == on_eye[t[2]];
    if (!mouth_fill && !eye_fill) nodes.tris.push_back(t);
  }
  return nodes;
}

// The inner-lip loop in the direction the skin's triangles traverse it, with the side of each
// vertex: +1 upper lip, −1 lower lip, 0 corners; and a smooth version sin(π k / 10) around the
// loop (k from corner 78) for the cavity's lens-shaped cross-section.
struct LipLoop {
  LoopRing ids{};  // ordered so that ids[k]→ids[k+1] is a skin edge
  std::array<double, kLoopSize> side{}, smooth_side{};
};

// Orders the loop after the opened skin (a boundary edge a→b of the skin) and marks each loop
// vertex's side in `nodes`.
LipLoop order_lip_loop(SoftNodes& nodes) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
  for (const auto& t : nodes.tris)
    for (int e = 0; e < 3; ++e) ++directed[{t[e], t[(e + 1) % 3]}];
  const bool forward = directed.count({kInnerLipLoop[0], kInnerLipLoop[1]}) > 0;
  LipLoop loop;
  for (std::size_t k = 0; k < kLoopSize; ++k)
    loop.ids[k] = forward ? kInnerLipLoop[k] : kInnerLipLoop[(kLoopSize - k) % kLoopSize];
  for (std::size_t k = 0; k < kLoopSize; ++k) {
    const auto id = loop.ids[k];
    const auto at =
        static_cast<std::size_t>(std::find(kInnerLipLoop.begin(), kInnerLipLoop.end(), id) - kInnerLipLoop.begin());
    loop.side[k] = (at >= kUpperBegin && at < kUpperEnd) ? 1.0 : (at >= kLowerBegin && at < kLowerEnd) ? -1.0 : 0.0;
    loop.smooth_side[k] = std::sin(std::numbers::pi * static_cast<double>(at) / 10.0);
    nodes.side[id] = loop.side[k];
  }
  return loop;
}

// Brings the lips together for the rest pose. The asset rests with the lips 5.5 mm apart (13→14)
// and the upper incisors showing; a face at rest has them together. At each x between the
// corners the upper and lower lip lines (the loop, linear between its vertices) are d(x) apart in
// height and depth; each lip moves half of d toward the other in both, less half of `rest_gap_m`
// in height, and the skin above (below) the line follows with a weight falling from 1 within 4 mm
// of the line to 0 at 18 mm (the vermilion moves whole; the skin toward the nose and the chin takes
// up the difference). x does not change and the mouth centre, the teeth and the jaw's geometry are
// the asset's. Springs take their rest lengths from this pose: it is the stress-free shape.
void close_lips_at_rest(SoftNodes& nodes, const LipLoop& loop, double rest_gap_m) {
  std::vector<Vec3> upper, lower;  // lip lines through both corners, by increasing x
  for (std::size_t k = 0; k < kLoopSize; ++k) {
    const Vec3 p = nodes.pos[loop.ids[k]];
    if (loop.side[k] >= 0.0) upper.push_back(p);
    if (loop.side[k] <= 0.0) lower.push_back(p);
  }
  auto by_x = [](Vec3 a, Vec3 b) { return a.x < b.x; };
  std::sort(upper.begin(), upper.end(), by_x);
  std::sort(lower.begin(), lower.end(), by_x);
  auto at_x = [](const std::vector<Vec3>& line, double x) {
    for (std::size_t k = 1; k < line.size(); ++k)
      if (x <= line[k].x) {
        const double t = (x - line[k - 1].x) / (line[k].x - line[k - 1].x);
        return (1.0 - t) * line[k - 1] + t * line[k];
      }
    return line.back();
  };
  const double x_min = std::max(upper.front().x, lower.front().x), x_max = std::min(upper.back().x, lower.back().x);
  std::vector<int> on_loop(nodes.pos.size(), 0);  // +1 upper, −1 lower, 2 corner
  for (std::size_t k = 0; k < kLoopSize; ++k)
    on_loop[loop.ids[k]] = loop.side[k] > 0.0 ? 1 : loop.side[k] < 0.0 ? -1 : 2;
  for (std::size_t i = 0; i < nodes.pos.size(); ++i) {
    Vec3& p = nodes.pos[i];
    if (p.x <= x_min || p.x >= x_max || on_loop[i] == 2) continue;
    const Vec3 u = at_x(upper, p.x), l = at_x(lower, p.x);
    const double dy = u.y - l.y;
    if (dy <= rest_gap_m) continue;
    const Vec3 half_down{0.0, -0.5 * (dy - rest_gap_m), -0.5 * (u.z - l.z)};  // moves the upper lip
    double weight = 0.0;  // +1 moves like the upper lip, −1 like the lower
    if (on_loop[i] != 0)
      weight = on_loop[i];
    else if (p.y >= u.y)
      weight = 1.0 - smoothstep(0.004, 0.018, p.y - u.y);
    else if (p.y <= l.y)
      weight = -(1.0 - smoothstep(0.004, 0.018, l.y - p.y));
    nodes.shift[i] = weight * half_down;
    p = p + nodes.shift[i];
  }
}

// The closed lips' facing nodes (upper[k] ↔ lower[k], FaceMesh::upper_lip_line) put at their mean,
// `rest_gap_m` apart in height: after close_lips_at_rest the two lines still differ where a pair's
// x differ (up to 0.75 mm, on a line that curves back 10 mm toward the corners), enough to leave a
// slit that shows the teeth as a line of light in the preview. Pairs still apart stay as they are.
void seal_lip_pairs(SoftNodes& nodes, const std::vector<std::uint32_t>& upper, const std::vector<std::uint32_t>& lower,
                    double rest_gap_m) {
  for (std::size_t k = 0; k < upper.size(); ++k) {
    Vec3& u = nodes.pos[upper[k]];
    Vec3& l = nodes.pos[lower[k]];
    if (u.y - l.y > rest_gap_m + 0.0005) continue;
    const Vec3 mean = 0.5 * (u + l);
    u = mean + Vec3{0.0, 0.5 * rest_gap_m, 0.0};
    l = mean + Vec3{0.0, -0.5 * rest_gap_m, 0.0};
  }
}

// Rings behind the lip line: inner lip (1, 2) and cavity (3, 4), then a fan to one vertex at the
// back. Returns the rings, the lip loop first.
std::vector<LoopRing> add_mouth_cavity(SoftNodes& nodes, const LipLoop& loop, Vec3 centre) {
  struct RingShape {
    double x_scale, vertical_m, back_m;
    bool smooth_side, from_centre_z;
  };
  constexpr std::array<RingShape, 4> kRings = {{
      {0.97, 0.0010, 0.003, false, false},  // mucosa just behind the lip line
      {0.93, 0.0040, 0.007, false, false},  // toward the gums (sulcus)
      {1.05, 0.0140, 0.016, true, false},   // cavity, around the teeth
      {0.80, 0.0160, 0.042, true, true},    // cavity, toward the pharynx
  }};
  std::vector<LoopRing> rings = {loop.ids};
  for (std::size_t r = 0; r < kRings.size(); ++r) {
    const RingShape& shape = kRings[r];
    LoopRing ring{};
    for (std::size_t k = 0; k < kLoopSize; ++k) {
      // The mucosa just behind the lip line closes with the lips; the sulcus and the cavity keep
      // the asset's heights (a sulcus at the closed lips' height lay on the lower incisal edge).
      Vec3 p = nodes.pos[loop.ids[k]];
      if (r > 0) p = p + -1.0 * nodes.shift[loop.ids[k]];
      const double s = shape.smooth_side ? loop.smooth_side[k] : loop.side[k];
      Vec3 q{centre.x + shape.x_scale * (p.x - centre.x), p.y + s * shape.vertical_m,
             (shape.from_centre_z ? centre.z : p.z) - shape.back_m};
      if (shape.smooth_side) q.y = centre.y + 0.4 * (p.y - centre.y) + s * shape.vertical_m;
      ring[k] = nodes.add(q, nodes.uv[loop.ids[k]], static_cast<double>(r + 1),
                          loop.side[k] != 0.0 ? loop.side[k] : (r >= 2 ? (s >= 0 ? 1.0 : -1.0) : 0.0));
    }
    rings.push_back(ring);
  }
  const auto back = nodes.add({centre.x, centre.y - 0.002, centre.z - 0.052}, nodes.uv[13], 5.0, 0.0);
  for (std::size_t r = 0; r + 1 < rings.size(); ++r) {
    for (std::size_t k = 0; k < kLoopSize; ++k) {
      const auto v0 = rings[r][k], v1 = rings[r][(k + 1) % kLoopSize];
      const auto w0 = rings[r + 1][k], w1 = rings[r + 1][(k + 1) % kLoopSize];
      nodes.tris.push_back({v1, v0, w0});
      nodes.tris.push_back({v1, w0, w1});
    }
  }
  for (std::size_t k = 0; k < kLoopSize; ++k)
    nodes.tris.push_back({rings.back()[(k + 1) % kLoopSize], rings.back()[k], back});
  return rings;
}

// One lip of a ring as a polyline: from corner to corner through the wanted side, ordered right
// (x < 0) to left, with both corners.
std::vector<std::uint32_t> lip_line(const SoftNodes& nodes, const LoopRing& ring, double wanted_side) {
  const auto& side = nodes.side;
  std::vector<std::uint32_t> line;
  std::size_t start = 0;
  for (std::size_t k = 0; k < kLoopSize; ++k)
    if (side[ring[k]] == wanted_side && side[ring[(k + kLoopSize - 1) % kLoopSize]] != wanted_side) start = k;
  line.push_back(ring[(start + kLoopSize - 1) % kLoopSize]);
  for (std::size_t k = start; side[ring[k % kLoopSize]] == wanted_side; ++k) line.push_back(ring[k % kLoopSize]);
  line.push_back(ring[(start + line.size() - 1) % kLoopSize]);
  if (nodes.pos[line.front()].x > nodes.pos[line.back()].x) std::reverse(line.begin(), line.end());
  return line;
}

// The lip lines of rings 0 (the lip line) and 1 (behind it), each with both corners.
struct LipLines {
  std::vector<std::uint32_t> upper0, lower0, upper1, lower1;
};

// Subdivides `levels` times, carrying positions, UVs, ring depth and side to the midpoints, and
// refining the lip lines as polylines.
void subdivide_soft_nodes(SoftNodes& nodes, LipLines& lines, int levels) {
  for (int level = 0; level < levels; ++level) {
    const auto old_count = static_cast<std::uint32_t>(nodes.pos.size());
    Subdivision sub = subdivide(nodes.tris, old_count);
    std::unordered_map<std::uint64_t, std::uint32_t> mid;
    for (std::size_t k = 0; k < sub.midpoint_parents.size(); ++k) {
      const auto [a, b] = sub.midpoint_parents[k];
      mid[edge_key(a, b)] = old_count + static_cast<std::uint32_t>(k);
      const auto& pos = nodes.pos;
      const auto& uv = nodes.uv;
      nodes.add(0.5 * (pos[a] + pos[b]), {0.5 * (uv[a][0] + uv[b][0]), 0.5 * (uv[a][1] + uv[b][1])},
                0.5 * (nodes.depth[a] + nodes.depth[b]), 0.5 * (nodes.side[a] + nodes.side[b]),
                0.5 * (nodes.shift[a] + nodes.shift[b]));
    }
    for (auto* line : {&lines.upper0, &lines.lower0, &lines.upper1, &lines.lower1}) {
      std::vector<std::uint32_t> refined{line->front()};
      for (std::size_t k = 1; k < line->size(); ++k) {
        refined.push_back(mid.at(edge_key((*line)[k - 1], (*line)[k])));
        refined.push_back((*line)[k]);
      }
      *line = std::move(refined);
    }
    nodes.tris = std::move(sub.triangles);
  }
}

// Jaw weights. Lip-line rings follow their side (upper lip on the skull, lower on the jaw).
// Skin follows the plane through the hinge axis and the mouth centre: below it the jaw, above it
// the skull, blended over a band 2 mm wide at the mouth that widens by half the lateral distance
// (cheeks stretch between the bones) and drops laterally so the upper cheeks stay on the skull.
void assign_jaw_weights(FaceMesh& mesh, const SoftNodes& nodes, const LipLines& lines) {
  const Vec3 centre = mesh.mouth_centre_m;
  const Vec3 hinge = mesh.anatomy.jaw_hinge_m;
  const double slope = (centre.y - hinge.y) / (centre.z - hinge.z);
  mesh.jaw_weights.resize(nodes.pos.size());
  for (std::size_t i = 0; i < nodes.pos.size(); ++i) {
    const Vec3 p = nodes.pos[i] + -1.0 * nodes.shift[i];  // the asset's position
    if (nodes.depth[i] > 0.0) {
      mesh.jaw_weights[i] = std::clamp(0.5 - 0.5 * nodes.side[i], 0.0, 1.0);
      continue;
    }
    const double lateral = std::hypot(p.x - centre.x, std::max(0.0, centre.z - p.z));
    const double line_y = hinge.y + slope * (p.z - hinge.z) - 0.2 * lateral;
    const double band = 0.002 + 0.5 * lateral;
    mesh.jaw_weights[i] = smoothstep(band, -band, p.y - line_y);
  }
  for (const auto id : lines.upper0) mesh.jaw_weights[id] = 0.0;
  for (const auto id : lines.lower0) mesh.jaw_weights[id] = 1.0;
  mesh.jaw_weights[mesh.mouth_corners[0]] = mesh.jaw_weights[mesh.mouth_corners[1]] = 0.5;
}

// An eye contour as two polylines by increasing x: the upper lid and the lower lid, both corners in each.
struct EyeLids {
  std::vector<Vec3> upper, lower;
};

EyeLids eye_lids(const std::vector<Vec3>& pos, const std::array<std::uint32_t, 16>& contour) {
  EyeLids lids;
  for (std::size_t k = 0; k <= 8; ++k) lids.upper.push_back(pos[contour[k]]);
  for (std::size_t k = 8; k <= 16; ++k) lids.lower.push_back(pos[contour[k % 16]]);
  auto by_x = [](Vec3 a, Vec3 b) { return a.x < b.x; };
  std::sort(lids.upper.begin(), lids.upper.end(), by_x);
  std::sort(lids.lower.begin(), lids.lower.end(), by_x);
  return lids;
}

double height_at(const std::vector<Vec3>& line, double x) {
  for (std::size_t k = 1; k < line.size(); ++k)
    if (x <= line[k].x) {
      const double t = (x - line[k - 1].x) / (line[k].x - line[k - 1].x);
      return line[k - 1].y + t * (line[k].y - line[k - 1].y);
    }
  return line.back().y;
}

// Eyeballs: an ellipsoid per eye behind its opening, as three rigid parts with their own vertices
// (so the colours' edges are sharp): a pupil cap within 0.16 rad of the front, the iris out to
// 0.5 rad (a 5.8 mm radius on a 12 mm ball), the white to a little past the equator.
void add_eyes(FaceMesh& mesh) {
  constexpr int kSectors = 16;
  struct Band {
    double from_rad, to_rad;
    int rings;
    FacePart part;
  };
  constexpr std::array<Band, 3> kBands = {
      {{0.0, 0.16, 1, FacePart::pupil}, {0.16, 0.50, 2, FacePart::iris}, {0.50, 1.75, 4, FacePart::eye_white}}};
  mesh.eyes_begin = static_cast<std::uint32_t>(mesh.rest_positions_m.size());
  const FaceAnatomy& anatomy = mesh.anatomy;
  for (std::size_t eye = 0; eye < 2; ++eye) {
    const auto& contour = kEyeContours[eye];
    const EyeLids lids = eye_lids(mesh.rest_positions_m, contour);
    Vec3 centre{0.5 * (lids.upper.front().x + lids.upper.back().x), 0.0, 0.0};
    for (const auto id : contour) centre.y += mesh.rest_positions_m[id].y / 16.0;
    const Vec3 top = mesh.rest_positions_m[contour[4]], bottom = mesh.rest_positions_m[contour[12]];
    const double front_z = 0.5 * (top.z + bottom.z) - anatomy.eyeball_behind_lids_m;
    const Vec3 axes{0.5 * (lids.upper.back().x - lids.upper.front().x) + 0.001, anatomy.eyeball_radius_m,
                    anatomy.eyeball_radius_m};
    centre.z = front_z - axes.z;
    mesh.eyeballs[eye] = {centre, axes};
    auto point = [&](double polar, double azimuth) {
      return Vec3{centre.x + axes.x * std::sin(polar) * std::cos(azimuth),
                  centre.y + axes.y * std::sin(polar) * std::sin(azimuth), centre.z + axes.z * std::cos(polar)};
    };
    for (const Band& band : kBands) {
      const auto base = static_cast<std::uint32_t>(mesh.rest_positions_m.size());
      auto push = [&](Vec3 p) {
        mesh.rest_positions_m.push_back(p);
        mesh.uvs.push_back({0.0F, 0.0F});
        mesh.parts.push_back(band.part);
      };
      // Rings r = 0 … rings at polar angles from → to (a pole instead of ring 0 when from = 0).
      const bool pole = band.from_rad == 0.0;
      if (pole) push(point(0.0, 0.0));
      for (int r = pole ? 1 : 0; r <= band.rings; ++r)
        for (int j = 0; j < kSectors; ++j)
          push(point(band.from_rad + (band.to_rad - band.from_rad) * r / band.rings,
                     2.0 * std::numbers::pi * j / kSectors));
      auto ring = [&](int r, int j) {
        const int first = pole ? 1 : 0;
        return base + (pole ? 1U : 0U) + static_cast<std::uint32_t>((r - first) * kSectors + (j % kSectors));
      };
      for (int j = 0; j < kSectors; ++j) {
        // Counter-clockwise seen from the front (+z), outside the ball.
        if (pole) mesh.triangles.push_back({base, ring(1, j), ring(1, j + 1)});
        for (int r = pole ? 1 : 0; r < band.rings; ++r) {
          mesh.triangles.push_back({ring(r, j), ring(r + 1, j), ring(r + 1, j + 1)});
          mesh.triangles.push_back({ring(r, j), ring(r + 1, j + 1), ring(r, j + 1)});
        }
      }
    }
  }
}

// Blinks: the upper lid's nodes and the skin above them (weight 1 at the lid margin, 0 at 6 mm
// above it) move down by the opening between the lids at their x and 0.3 mm more, so the shut
// upper lid overlaps the lower one (lids that just met left a line of white in the preview).
void add_blink(FaceMesh& mesh) {
  for (std::size_t eye = 0; eye < 2; ++eye) {
    const EyeLids lids = eye_lids(mesh.rest_positions_m, kEyeContours[eye]);
    const double x_min = lids.upper.front().x, x_max = lids.upper.back().x;
    for (std::uint32_t i = 0; i < mesh.soft_node_count; ++i) {
      if (mesh.ring_depth[i] != 0.0) continue;
      const Vec3 p = mesh.rest_positions_m[i];
      if (p.x <= x_min || p.x >= x_max) continue;
      const double y_upper = height_at(lids.upper, p.x), y_lower = height_at(lids.lower, p.x);
      const double above = p.y - y_upper;
      if (above < -1e-9 || above > 0.006) continue;
      const double weight = 1.0 - smoothstep(0.0, 0.006, above);
      const double drop = std::max(y_upper - y_lower, 0.0) + 0.0003;
      mesh.blink_nodes.push_back(i);
      mesh.blink_offsets_m.push_back({0.0, -weight * drop, 0.0});
      mesh.blink_eye.push_back(static_cast<std::uint8_t>(eye));
    }
  }
}

// The soft nodes become the mesh's first vertices, each with its part by ring depth.
void store_soft_nodes(FaceMesh& mesh, SoftNodes&& nodes) {
  mesh.rest_positions_m = std::move(nodes.pos);
  for (const auto& t : nodes.uv) mesh.uvs.push_back({static_cast<float>(t[0]), static_cast<float>(t[1])});
  mesh.triangles = std::move(nodes.tris);
  mesh.ring_depth = std::move(nodes.depth);
  for (std::size_t i = 0; i < mesh.soft_node_count; ++i)
    mesh.parts.push_back(mesh.ring_depth[i] == 0.0   ? FacePart::skin
                         : mesh.ring_depth[i] <= 2.0 ? FacePart::inner_lip
                                                     : FacePart::mouth_cavity);
}

// Teeth: elliptic arches (x semi-axis a, z semi-axis b) whose front passes teeth_front_z at x = 0.
// The inner lips rest outside the teeth (by 1 mm), so the rest pose satisfies the contacts.
void add_teeth(FaceMesh& mesh, double teeth_front_z) {
  const FaceAnatomy& anatomy = mesh.anatomy;
  const Vec3 centre = mesh.mouth_centre_m;
  mesh.upper_arch_a_m = anatomy.arch_half_width_m;
  mesh.upper_arch_b_m = anatomy.arch_depth_m;
  mesh.upper_arch_centre_z_m = teeth_front_z - mesh.upper_arch_b_m;
  mesh.upper_teeth_y_min_m = centre.y - anatomy.upper_teeth_edge_below_centre_m;
  mesh.upper_teeth_y_max_m = mesh.upper_teeth_y_min_m + anatomy.teeth_height_m;
  mesh.lower_arch_a_m = anatomy.arch_half_width_m - anatomy.overjet_m;
  mesh.lower_arch_b_m = anatomy.arch_depth_m - anatomy.overjet_m;
  mesh.lower_arch_centre_z_m = mesh.upper_arch_centre_z_m;
  mesh.lower_teeth_y_max_m = centre.y + anatomy.lower_teeth_edge_above_centre_m;
  mesh.lower_teeth_y_min_m = mesh.lower_teeth_y_max_m - anatomy.teeth_height_m;
  mesh.upper_teeth_begin = mesh.soft_node_count;
  add_arch(mesh, mesh.upper_arch_centre_z_m, mesh.upper_arch_a_m, mesh.upper_arch_b_m, anatomy.teeth_thickness_m,
           mesh.upper_teeth_y_min_m, mesh.upper_teeth_y_max_m, FacePart::upper_teeth);
  mesh.lower_teeth_begin = static_cast<std::uint32_t>(mesh.rest_positions_m.size());
  add_arch(mesh, mesh.lower_arch_centre_z_m, mesh.lower_arch_a_m, mesh.lower_arch_b_m, anatomy.teeth_thickness_m,
           mesh.lower_teeth_y_min_m, mesh.lower_teeth_y_max_m, FacePart::lower_teeth);
  for (std::uint32_t i = 0; i < mesh.soft_node_count; ++i) {
    if (mesh.ring_depth[i] == 0.0 || mesh.ring_depth[i] > 2.5) continue;
    Vec3& p = mesh.rest_positions_m[i];
    detail::push_out_of_arch(p, mesh.upper_arch_centre_z_m, mesh.upper_arch_a_m, mesh.upper_arch_b_m,
                             mesh.upper_teeth_y_min_m, mesh.upper_teeth_y_max_m, 0.001);
    detail::push_out_of_arch(p, mesh.lower_arch_centre_z_m, mesh.lower_arch_a_m, mesh.lower_arch_b_m,
                             mesh.lower_teeth_y_min_m, mesh.lower_teeth_y_max_m, 0.001);
  }
}

}  // namespace

FaceAsset FaceAsset::from_json(std::string_view json_text, std::string_view source) {
  const std::string src(source);
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(json_text);
  } catch (const nlohmann::json::exception& e) {  // parse_error, and out_of_range for a number that overflows
    throw InputError(src, 0, std::string("not valid JSON: ") + e.what());
  }
  FaceAsset asset;
  try {
    if (doc.at("format") != "lipsync-face-asset") throw InputError(src, 0, "field 'format' must be lipsync-face-asset");
    for (const auto& p : doc.at("positions_cm")) asset.positions_cm.push_back({p.at(0), p.at(1), p.at(2)});
    for (const auto& uv : doc.at("uvs")) asset.uvs.push_back({uv.at(0).get<double>(), uv.at(1).get<double>()});
    for (const auto& t : doc.at("triangles")) asset.triangles.push_back({t.at(0), t.at(1), t.at(2)});
  } catch (const nlohmann::json::exception& e) {
    throw InputError(src, 0, std::string("bad face asset: ") + e.what());
  }
  if (asset.uvs.size() != asset.positions_cm.size())
    throw InputError(src, 0, "field 'uvs' must have one entry per position");
  for (std::size_t t = 0; t < asset.triangles.size(); ++t)
    for (const auto index : asset.triangles[t])
      if (index >= asset.positions_cm.size())
        throw InputError(src, 0,
                         "triangle " + std::to_string(t) + " names vertex " + std::to_string(index) + " of " +
                             std::to_string(asset.positions_cm.size()));
  return asset;
}

const FaceAsset& FaceAsset::builtin() {
  static const FaceAsset kAsset = from_json(embedded::canonical_face_json(), "data/face/canonical_face.json");
  return kAsset;
}

Subdivision subdivide(std::span<const std::array<std::uint32_t, 3>> triangles, std::uint32_t vertex_count) {
  Subdivision out;
  std::unordered_map<std::uint64_t, std::uint32_t> midpoint;
  auto mid = [&](std::uint32_t a, std::uint32_t b) {
    const auto [it, inserted] = midpoint.try_emplace(edge_key(a, b), 0);
    if (inserted) {
      it->second = vertex_count + static_cast<std::uint32_t>(out.midpoint_parents.size());
      out.midpoint_parents.push_back({std::min(a, b), std::max(a, b)});
    }
    return it->second;
  };
  out.triangles.reserve(triangles.size() * 4);
  for (const auto& [a, b, c] : triangles) {
    const auto ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
    out.triangles.push_back({a, ab, ca});
    out.triangles.push_back({ab, b, bc});
    out.triangles.push_back({ca, bc, c});
    out.triangles.push_back({ab, bc, ca});
  }
  return out;
}

FaceMesh build_face_mesh(const FaceAsset& asset, int subdivision_level, const FaceAnatomy& anatomy) {
  checked_mesh_subdivision(subdivision_level, "subdivision_level");
  FaceMesh mesh;
  mesh.anatomy = anatomy;
  mesh.subdivision_level = subdivision_level;

  SoftNodes nodes = open_mouth(asset);
  const LipLoop loop = order_lip_loop(nodes);
  const Vec3 centre = 0.5 * (nodes.pos[13] + nodes.pos[14]);
  mesh.mouth_centre_m = centre;
  const double teeth_front_z = nodes.pos[13].z - anatomy.upper_teeth_depth_m;
  close_lips_at_rest(nodes, loop, anatomy.rest_lip_gap_m);
  const std::vector<LoopRing> rings = add_mouth_cavity(nodes, loop, centre);

  LipLines lines{lip_line(nodes, rings[0], 1.0), lip_line(nodes, rings[0], -1.0), lip_line(nodes, rings[1], 1.0),
                 lip_line(nodes, rings[1], -1.0)};
  mesh.mouth_corners = {lines.upper0.front(), lines.upper0.back()};
  subdivide_soft_nodes(nodes, lines, subdivision_level);
  auto interior = [](const std::vector<std::uint32_t>& line) {
    return std::vector<std::uint32_t>(line.begin() + 1, line.end() - 1);
  };
  mesh.upper_lip_line = interior(lines.upper0);
  mesh.lower_lip_line = interior(lines.lower0);
  mesh.upper_inner_ring = interior(lines.upper1);
  mesh.lower_inner_ring = interior(lines.lower1);
  seal_lip_pairs(nodes, mesh.upper_lip_line, mesh.lower_lip_line, anatomy.rest_lip_gap_m);

  mesh.soft_node_count = static_cast<std::uint32_t>(nodes.pos.size());
  assign_jaw_weights(mesh, nodes, lines);
  store_soft_nodes(mesh, std::move(nodes));
  add_teeth(mesh, teeth_front_z);
  mesh.tongue_begin = static_cast<std::uint32_t>(mesh.rest_positions_m.size());
  const Vec3 r = anatomy.tongue_semi_axes_m;
  mesh.tongue_centre_m = {centre.x, centre.y - anatomy.tongue_below_centre_m,
                          teeth_front_z - anatomy.tongue_tip_behind_teeth_m - r.z};
  mesh.tongue_root_m = {centre.x, mesh.tongue_centre_m.y - r.y, mesh.tongue_centre_m.z - r.z};
  add_tongue(mesh);
  add_eyes(mesh);
  add_blink(mesh);
  return mesh;
}

}  // namespace lipsync::face
