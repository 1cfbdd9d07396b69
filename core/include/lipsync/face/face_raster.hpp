// A tiny software rasteriser for previews of the simulated face: a pose in, an RGB image out.
//
// The camera looks at the mouth from the front along −z (perspective, a pinhole `camera_distance_m`
// in front of the mouth centre, slightly above it); triangles are filled with a z-buffer and
// two-sided Lambert shading from one key light plus ambient. The colour is the vertex part's
// (skin, inner lip, mouth cavity, teeth, tongue; part_colour()), interpolated over the triangle,
// then gamma-encoded to sRGB. Pure: no files, no threads, deterministic.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "lipsync/face/face_mesh.hpp"

namespace lipsync::face {

struct RasterOptions {
  int width = 480;
  int height = 480;
  double camera_distance_m = 0.42;
  double camera_height_m = 0.01;         ///< above the mouth centre
  double field_of_view_deg = 26.0;       ///< vertical
  double look_at_above_mouth_m = 0.025;  ///< the view centre, above the mouth centre
  std::array<std::uint8_t, 3> background{40, 44, 52};
};

/// Renders `positions` (mesh.vertex_count() vertices, metres) into `rgb` (width × height × 3
/// bytes, rows top to bottom), resized as needed. Throws std::invalid_argument for a size below 1
/// or a vertex count that is not the mesh's.
void render_face_rgb(const FaceMesh& mesh, std::span<const Vec3> positions, const RasterOptions& options,
                     std::vector<std::uint8_t>& rgb);

}  // namespace lipsync::face
