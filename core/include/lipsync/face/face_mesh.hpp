// The face's geometry: the MediaPipe canonical face mesh opened at the mouth, given inner lips,
// a closed mouth cavity, two rigid teeth arches and a rigid tongue.
//
// The asset (data/face/canonical_face.json, docs/face.md) is a face mask in centimetres with the
// mouth and eyes filled. build_face_mesh() removes the 18 triangles that fill the mouth, leaving a
// 20-vertex inner-lip loop, and extrudes that loop backwards into rings: two rings of inner lip
// (mucosa curling back toward the gums), two rings of cavity and a closing fan, so the skin is one
// oriented surface. The soft surface is then split 1→4 at edge midpoints `subdivision_level` times
// (landmark ids 0–467 keep their index). Teeth and tongue are rigid meshes appended after the soft
// nodes; they are carried by their bone (skull, jaw, tongue) and never simulated. The eyes'
// fills (the asset's closed lids) are removed too, and behind each opening an eyeball (white,
// iris, pupil; rigid, on the skull) looks forward; the upper lids can close over them (blinks:
// blink_nodes, applied by FaceTrackStepper, face_animation.hpp).
//
// Everything here is in metres, in the asset's frame: x toward the subject's left, y up, z toward
// the viewer. Vertex order: soft nodes [0, soft_node_count), then upper teeth, lower teeth, tongue,
// eyes.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

namespace lipsync::face {

struct Vec3 {
  double x = 0, y = 0, z = 0;
};

/// The canonical mesh as shipped (centimetres), before any processing.
struct FaceAsset {
  std::vector<Vec3> positions_cm;
  std::vector<std::array<double, 2>> uvs;
  std::vector<std::array<std::uint32_t, 3>> triangles;

  /// Parses the lipsync-face-asset JSON format. Throws InputError naming `source` and the field.
  static FaceAsset from_json(std::string_view json_text, std::string_view source);
  /// data/face/canonical_face.json as embedded in the library.
  static const FaceAsset& builtin();
};

/// The 20 inner-lip landmark ids, in boundary order: corner 78, upper lip to corner 308, lower lip.
extern const std::array<std::uint32_t, 20> kInnerLipLoop;

/// What a vertex belongs to (for rendering materials and for the solver).
enum class FacePart : std::uint8_t {
  skin,
  inner_lip,
  mouth_cavity,
  upper_teeth,
  lower_teeth,
  tongue,
  eye_white,  ///< the eyeball's sclera (rigid, skull)
  iris,
  pupil
};

/// The eye contours of the canonical mesh (landmark ids), the subject's right eye then the left:
/// corner, upper lid (7), corner, lower lid (7) back to the first corner.
extern const std::array<std::array<std::uint32_t, 16>, 2> kEyeContours;

/// An eyeball: an ellipsoid behind an eye opening, looking forward (+z), metres.
struct EyeBall {
  Vec3 centre_m;
  Vec3 semi_axes_m;
};

/// Anatomy that the asset lacks, in metres relative to landmarks. Defaults fit the canonical mesh.
struct FaceAnatomy {
  /// Temporomandibular hinge: a point of the jaw's rotation axis (the x axis through it), metres.
  Vec3 jaw_hinge_m{0.0, -0.005, -0.035};
  /// Upper incisors' labial face at the midline lies this far behind inner-lip landmark 13.
  double upper_teeth_depth_m = 0.006;
  /// Incisal edge of the upper teeth below the mouth centre (mean of landmarks 13 and 14).
  double upper_teeth_edge_below_centre_m = 0.0015;
  /// Lower incisal edge above the mouth centre (overbite) and behind the upper arch (overjet).
  double lower_teeth_edge_above_centre_m = 0.0005;
  double overjet_m = 0.0025;
  double teeth_height_m = 0.010;     ///< visible crown height
  double teeth_thickness_m = 0.007;  ///< labial-lingual
  double arch_half_width_m = 0.024;  ///< x semi-axis of the upper arch ellipse
  double arch_depth_m = 0.028;       ///< z semi-axis of the upper arch ellipse
  /// Tongue: ellipsoid semi-axes and its tip's distance behind the upper teeth front.
  Vec3 tongue_semi_axes_m{0.021, 0.008, 0.028};
  double tongue_tip_behind_teeth_m = 0.006;
  double tongue_below_centre_m = 0.011;
  /// Gap left between the lips at rest over the middle of the mouth: the asset's lips (5.5 mm
  /// apart) are brought together to it, and the skin around them follows (docs/face.md).
  double rest_lip_gap_m = 0.0;
  /// Eyeball depth (z semi-axis) and height; its width spans the eye opening plus 1 mm. Its front
  /// lies `eyeball_behind_lids_m` behind the lid margins' middle (landmarks 159 / 145, 386 / 374).
  double eyeball_radius_m = 0.012;
  double eyeball_behind_lids_m = 0.0015;
};

struct FaceMesh {
  /// Rest positions of all vertices (soft nodes first), metres.
  std::vector<Vec3> rest_positions_m;
  /// Texture coordinates from the asset; generated vertices take their lip-loop vertex's UV
  /// (inner lip, cavity) or (0, 0) (teeth, tongue).
  std::vector<std::array<float, 2>> uvs;
  /// Triangles, counter-clockwise seen from outside the face (from inside the mouth for the cavity).
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::vector<FacePart> parts;  ///< per vertex
  /// Per soft node: how much it follows the jaw at rest (0 skull .. 1 jaw), before muscle bindings.
  std::vector<double> jaw_weights;
  /// Per soft node: rings behind the lip line (0 skin and lip line, 1–2 inner lip, ≥3 cavity);
  /// fractional for midpoints between rings.
  std::vector<double> ring_depth;

  std::uint32_t soft_node_count = 0;
  std::uint32_t upper_teeth_begin = 0, lower_teeth_begin = 0, tongue_begin = 0, eyes_begin = 0;  ///< vertex ranges
  int subdivision_level = 0;

  /// Lip lines (ring 0), corner excluded, ordered from the subject's right to left: the upper and
  /// lower lists have equal length and element k of one faces element k of the other.
  std::vector<std::uint32_t> upper_lip_line, lower_lip_line;
  /// The same pairing for inner-lip ring 1 (behind the lip line).
  std::vector<std::uint32_t> upper_inner_ring, lower_inner_ring;
  std::array<std::uint32_t, 2> mouth_corners{};  ///< right (78), left (308)

  FaceAnatomy anatomy;
  Vec3 mouth_centre_m;  ///< mean of landmarks 13 and 14 in the asset (the lips close on it at rest)
  /// Upper-teeth arch, skull frame: ellipse centre (x, z), semi-axes, and y range.
  double upper_arch_centre_z_m = 0, lower_arch_centre_z_m = 0;
  double upper_arch_a_m = 0, upper_arch_b_m = 0, lower_arch_a_m = 0, lower_arch_b_m = 0;
  double upper_teeth_y_min_m = 0, upper_teeth_y_max_m = 0, lower_teeth_y_min_m = 0, lower_teeth_y_max_m = 0;
  Vec3 tongue_centre_m, tongue_root_m;
  std::array<EyeBall, 2> eyeballs{};  ///< right, left
  /// A blink: soft nodes of the upper lids (and the skin above them, fading out over 6 mm) and
  /// their displacement when the lids are shut (blink_offsets_m[k] for node blink_nodes[k]); a
  /// lid closed by s in [0, 1] is rest + s · offset, kept outside its eyeball.
  std::vector<std::uint32_t> blink_nodes;
  std::vector<Vec3> blink_offsets_m;
  std::vector<std::uint8_t> blink_eye;  ///< 0 right, 1 left, per blink node

  std::size_t vertex_count() const { return rest_positions_m.size(); }
};

/// One level of 1→4 midpoint subdivision: every edge gets a vertex at its midpoint, inserted after
/// the existing vertices in order of first appearance; `edge_midpoint` (optional out) maps a sorted
/// edge key (a << 32 | b, a < b) to its midpoint's index.
struct Subdivision {
  std::vector<std::array<std::uint32_t, 3>> triangles;
  std::vector<std::array<std::uint32_t, 2>> midpoint_parents;  ///< new vertex k: parents of vertex (old count + k)
};
Subdivision subdivide(std::span<const std::array<std::uint32_t, 3>> triangles, std::uint32_t vertex_count);

/// Builds the face at `subdivision_level` 0, 1 or 2 (about 0.5k, 1.9k, 7.3k soft nodes).
/// Throws std::invalid_argument for another level.
FaceMesh build_face_mesh(const FaceAsset& asset, int subdivision_level, const FaceAnatomy& anatomy = {});

}  // namespace lipsync::face
