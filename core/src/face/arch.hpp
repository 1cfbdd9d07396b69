// The teeth as collision shapes: an elliptic arch band (x semi-axis a, z semi-axis b, centred at
// (0, centre_z) in its bone's frame) between y_min and y_max. Shared by the mesh builder, which
// puts the inner lips' rest positions outside the teeth, and the solver, which keeps them there.
#pragma once

#include <algorithm>
#include <cmath>

#include "lipsync/face/face_mesh.hpp"

namespace lipsync::face::detail {

/// Moves p (bone frame) radially from the arch centre to `margin_m` outside the labial surface if
/// it lies inside the arch's front half. Returns whether it moved.
inline bool push_out_of_arch(Vec3& p, double centre_z, double a, double b, double y_min, double y_max,
                             double margin_m) {
  if (p.y < y_min || p.y > y_max || p.z <= centre_z) return false;
  const double u = p.x / (a + margin_m), w = (p.z - centre_z) / (b + margin_m);
  const double e = u * u + w * w;
  if (e >= 1.0) return false;
  const double s = 1.0 / std::sqrt(std::max(e, 1e-12));
  p.x *= s;
  p.z = centre_z + s * (p.z - centre_z);
  return true;
}

}  // namespace lipsync::face::detail
