// The muscle rig: which muscles pull the skin where, and how the jaw and tongue channels pose
// the bones. It is data (data/face/rig.json, format in docs/face.md), validated once against an
// articulation model: the rig's muscles are exactly the model's channels of kind "muscle", and the
// jaw and tongue channels are named by the rig. After loading, every lookup is by channel index.
//
// A muscle is one or more fibres, each a polyline over landmark ids (0–467) from origin to
// insertion (Kähler et al. 2001). Skin nodes within a fibre's radius are bound to it. A linear
// muscle's contraction c ∈ [0, 1] moves its bound skin toward the origin by c · max_shortening_m
// (full at the insertion, fading to zero toward the origin) and bulges it outward; a sphincter part
// of the orbicularis oris moves its lip toward the mouth's midline (closure), toward the centre
// (pursing) and forward (protrusion). The closure saturates: contraction beyond
// `closure_saturation` purses and protrudes the lip further but closes it no more, so that a
// strongly rounded vowel (/uw/, c ≈ 0.85) keeps an opening while a bilabial closure (c ≈ 0.4,
// with the mentalis) seals. The lower part also compensates the jaw: driven by the mentalis, it
// holds the lower lip up against the jaw's opening, so the lips seal over the few millimetres of
// incisor opening that real bilabials have. Each muscle rides on a bone: the skull, or the jaw.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/face/face_mesh.hpp"
#include "lipsync/model.hpp"

namespace lipsync::face {

enum class Bone : std::uint8_t { skull, jaw };
enum class MuscleKind : std::uint8_t { linear, sphincter };

struct FibreSpec {
  std::vector<std::uint32_t> path;  ///< landmark ids, origin first, insertion last (≥ 2)
  double radius_m = 0.01;           ///< skin within this distance of the polyline is bound
};

struct MuscleSpec {
  std::string name;  ///< equals a model channel name
  MuscleKind kind = MuscleKind::linear;
  Bone bone = Bone::skull;
  std::vector<FibreSpec> fibres;
  std::size_t channel = 0;  ///< index of the model channel driving it
  // Linear muscles.
  double max_shortening_m = 0.0;  ///< displacement of the insertion toward the origin at c = 1
  double mobile_from = 0.0;       ///< fibre parameter (0 origin, 1 insertion) where motion starts
  double bulge_m = 0.0;           ///< outward bulge of the belly at c = 1
  double origin_depth_m = 0.0;    ///< the origin lies on the bone this far behind (−z) its landmark
  // Sphincter parts.
  double closure_m = 0.0;           ///< motion along closure_direction per unit contraction …
  double closure_saturation = 1.0;  ///< … up to this contraction: closure = closure_m · min(c, this)
  Vec3 closure_direction{};         ///< unit vector (toward the lip midline)
  double purse = 0.0;               ///< fraction of the horizontal offset to the mouth centre removed at c = 1
  double protrusion_m = 0.0;        ///< forward (+z) motion at c = 1
  /// Motion against closure_direction at c = 1, beyond the saturation as the protrusion: the lip
  /// turns outward and parts from the other (rounding opens a lip-closed rest, docs/face.md).
  double eversion_m = 0.0;
  /// Lip–jaw compensation (optional, sphincter parts on the jaw): as the contraction of the
  /// `compensation_channel` rises from `compensation_from` to `compensation_full` (smoothstep), the
  /// part's bound lip holds up to `compensation_share` of its jaw-closed position against the jaw's
  /// opening, so that lips that mean to meet meet over an open jaw (motor equivalence: Abbs &
  /// Gracco 1984). kNoChannel when absent.
  static constexpr std::size_t kNoChannel = static_cast<std::size_t>(-1);
  std::size_t compensation_channel = kNoChannel;
  double compensation_from = 0.0;
  double compensation_full = 1.0;
  double compensation_share = 0.0;
};

class FaceRig {
 public:
  /// Parses and validates a rig against `model`. Throws InputError naming `source`, the muscle
  /// and the field for every problem (unknown or missing muscle, bad landmark id, bad value).
  static FaceRig from_json(std::string_view json_text, std::string_view source, const ArticulationModel& model);
  /// data/face/rig.json as embedded, validated against ArticulationModel::builtin().
  static const FaceRig& builtin();
  /// The JSON text of the embedded rig.
  static std::string_view builtin_json();

  const std::vector<MuscleSpec>& muscles() const { return muscles_; }
  std::size_t channel_count() const { return channel_count_; }
  std::size_t jaw_channel() const { return jaw_channel_; }
  double max_jaw_rotation_rad() const { return max_jaw_rotation_rad_; }  ///< at channel value 1
  /// The jaw value the soft tissue follows for jaw value `jaw` (rig.json "jaw": "seal_below",
  /// "seal_release"): j · smoothstep(seal_below, seal_release, j). Below seal_below the skin and
  /// lips stay where they rest while the teeth part (the lips keep their seal over the jaw's small
  /// opening at rest, the freeway space: silence holds the jaw at 0.02); from seal_release on the
  /// skin follows the jaw itself. `jaw` itself without a seal.
  double skin_jaw_value(double jaw) const;
  std::size_t tongue_raise_channel() const { return tongue_raise_channel_; }
  double max_tongue_raise_rad() const { return max_tongue_raise_rad_; }  ///< at channel value ±1
  std::size_t tongue_protrusion_channel() const { return tongue_protrusion_channel_; }
  double max_tongue_protrusion_m() const { return max_tongue_protrusion_m_; }  ///< at channel value 1

 private:
  std::vector<MuscleSpec> muscles_;
  std::size_t channel_count_ = 0;
  std::size_t jaw_channel_ = 0, tongue_raise_channel_ = 0, tongue_protrusion_channel_ = 0;
  double max_jaw_rotation_rad_ = 0, max_tongue_raise_rad_ = 0, max_tongue_protrusion_m_ = 0;
  double jaw_seal_below_ = 0, jaw_seal_release_ = 0;
};

}  // namespace lipsync::face
