// The preview rasteriser (face_raster.hpp): project, then per triangle a bounding-box scan with
// edge functions (top-left fill rule not needed for a preview: shared edges may be drawn twice),
// perspective-correct depth by interpolating 1/z_view, shading per vertex.
#include "lipsync/face/face_raster.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "lipsync/face/face_animation.hpp"

namespace lipsync::face {

void render_face_rgb(const FaceMesh& mesh, std::span<const Vec3> positions, const RasterOptions& options,
                     std::vector<std::uint8_t>& rgb) {
  if (options.width < 1 || options.height < 1) throw std::invalid_argument("render_face_rgb: empty image");
  if (positions.size() != mesh.vertex_count())
    throw std::invalid_argument("render_face_rgb: the pose's vertex count is not the mesh's");
  const int w = options.width, h = options.height;
  rgb.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3);
  for (std::size_t p = 0; p < rgb.size(); p += 3) {
    rgb[p] = options.background[0];
    rgb[p + 1] = options.background[1];
    rgb[p + 2] = options.background[2];
  }
  std::vector<float> depth(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0.0F);  // 1/z, larger is nearer

  // Camera: at eye, looking at target; right-handed, view z toward the camera.
  const Vec3 c = mesh.mouth_centre_m;
  const double ex = c.x, ey = c.y + options.camera_height_m, ez = c.z + options.camera_distance_m;
  const double tx = c.x, ty = c.y + options.look_at_above_mouth_m, tz = c.z;
  double fx = tx - ex, fy = ty - ey, fz = tz - ez;  // forward
  const double fl = std::sqrt(fx * fx + fy * fy + fz * fz);
  fx /= fl, fy /= fl, fz /= fl;
  // right = forward × up(0,1,0); up' = right × forward
  double rx = -fz, ry = 0.0, rz = fx;
  const double rl = std::sqrt(rx * rx + rz * rz);
  rx /= rl, rz /= rl;
  const double ux = ry * fz - rz * fy, uy = rz * fx - rx * fz, uz = rx * fy - ry * fx;
  const double focal_px = 0.5 * h / std::tan(0.5 * options.field_of_view_deg * std::numbers::pi / 180.0);

  struct Projected {
    double sx, sy, inv_z;
  };
  std::vector<Projected> screen(positions.size());
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const double dx = positions[i].x - ex, dy = positions[i].y - ey, dz = positions[i].z - ez;
    const double vx = dx * rx + dy * ry + dz * rz, vy = dx * ux + dy * uy + dz * uz;
    const double depth_m = std::max(dx * fx + dy * fy + dz * fz, 1e-6);
    screen[i] = {0.5 * w + focal_px * vx / depth_m, 0.5 * h - focal_px * vy / depth_m, 1.0 / depth_m};
  }
  // Key light from the upper left front, in world coordinates.
  double lx = -0.35, ly = 0.55, lz = 0.76;
  const double ll = std::sqrt(lx * lx + ly * ly + lz * lz);
  lx /= ll, ly /= ll, lz /= ll;

  // Smooth (Gouraud) shading: area-weighted vertex normals of this pose, two-sided Lambert per
  // vertex, colours interpolated over the triangle.
  std::vector<Vec3> normal(positions.size());
  for (const auto& t : mesh.triangles) {
    const Vec3 &a = positions[t[0]], &b = positions[t[1]], &d = positions[t[2]];
    const double e1x = b.x - a.x, e1y = b.y - a.y, e1z = b.z - a.z;
    const double e2x = d.x - a.x, e2y = d.y - a.y, e2z = d.z - a.z;
    const Vec3 n{e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x};
    for (const auto v : t) normal[v] = {normal[v].x + n.x, normal[v].y + n.y, normal[v].z + n.z};
  }
  const std::vector<std::array<float, 3>> base_colour = vertex_colours(mesh);
  std::vector<std::array<float, 3>> lit(positions.size());
  for (std::size_t v = 0; v < positions.size(); ++v) {
    const Vec3 n = normal[v];
    const double nl = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    const double lambert = nl > 0 ? std::abs(n.x * lx + n.y * ly + n.z * lz) / nl : 0.0;
    const auto shade = static_cast<float>(0.22 + 0.78 * lambert);
    lit[v] = {shade * base_colour[v][0], shade * base_colour[v][1], shade * base_colour[v][2]};
  }

  for (const auto& t : mesh.triangles) {
    const Projected &p0 = screen[t[0]], &p1 = screen[t[1]], &p2 = screen[t[2]];
    const double area = (p1.sx - p0.sx) * (p2.sy - p0.sy) - (p1.sy - p0.sy) * (p2.sx - p0.sx);
    if (std::abs(area) < 1e-12) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({p0.sx, p1.sx, p2.sx}))));
    const int x1 = std::min(w - 1, static_cast<int>(std::ceil(std::max({p0.sx, p1.sx, p2.sx}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({p0.sy, p1.sy, p2.sy}))));
    const int y1 = std::min(h - 1, static_cast<int>(std::ceil(std::max({p0.sy, p1.sy, p2.sy}))));
    const std::array<std::array<float, 3>, 3> colour{lit[t[0]], lit[t[1]], lit[t[2]]};
    for (int py = y0; py <= y1; ++py) {
      for (int px = x0; px <= x1; ++px) {
        const double sx = px + 0.5, sy = py + 0.5;
        const double w0 = ((p1.sx - sx) * (p2.sy - sy) - (p1.sy - sy) * (p2.sx - sx)) / area;
        const double w1 = ((p2.sx - sx) * (p0.sy - sy) - (p2.sy - sy) * (p0.sx - sx)) / area;
        const double w2 = 1.0 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const double inv_z = w0 * p0.inv_z + w1 * p1.inv_z + w2 * p2.inv_z;
        const std::size_t pixel =
            static_cast<std::size_t>(py) * static_cast<std::size_t>(w) + static_cast<std::size_t>(px);
        if (inv_z <= depth[pixel]) continue;
        depth[pixel] = static_cast<float>(inv_z);
        for (int k = 0; k < 3; ++k) {
          const auto kk = static_cast<std::size_t>(k);
          const double linear = (w0 * colour[0][kk] + w1 * colour[1][kk] + w2 * colour[2][kk]);
          const double srgb = linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
          rgb[3 * pixel + kk] = static_cast<std::uint8_t>(std::clamp(std::lround(255.0 * srgb), 0L, 255L));
        }
      }
    }
  }
}

}  // namespace lipsync::face
