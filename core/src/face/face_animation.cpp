// Track → simulated poses → glTF binary; the design is in face_animation.hpp and docs/face.md.
//
// GLB layout: a 12-byte header, a JSON chunk (padded with spaces) and a BIN chunk (padded with
// zeros). The BIN chunk holds, 4-byte aligned and in this order: triangle indices (uint32), base
// positions (float VEC3, the first frame), UVs (float VEC2), colours (float VEC3), one displacement
// per key frame (float VEC3, key − base), key times (float seconds) and the one-hot weights
// (float, keys × keys).
#include "lipsync/face/face_animation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "lipsync/setting_ranges.hpp"

namespace lipsync::face {

std::array<float, 3> part_colour(FacePart part) {
  switch (part) {
    case FacePart::skin:
      return {0.80F, 0.56F, 0.44F};
    case FacePart::inner_lip:
      return {0.62F, 0.20F, 0.22F};
    case FacePart::mouth_cavity:
      return {0.22F, 0.04F, 0.05F};
    case FacePart::upper_teeth:
    case FacePart::lower_teeth:
      return {0.92F, 0.90F, 0.84F};
    case FacePart::tongue:
      return {0.75F, 0.30F, 0.32F};
  }
  return {1.0F, 0.0F, 1.0F};
}

std::vector<std::array<float, 3>> vertex_colours(const FaceMesh& mesh) {
  static constexpr std::uint32_t kOuterLip[] = {61,  185, 40,  39,  37,  0,  267, 269, 270, 409,
                                                291, 375, 321, 405, 314, 17, 84,  181, 91,  146};
  constexpr std::array<float, 3> kLip{0.62F, 0.28F, 0.27F};
  std::vector<std::array<float, 3>> colours(mesh.vertex_count());
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    colours[v] = part_colour(mesh.parts[v]);
    if (mesh.parts[v] != FacePart::skin) continue;
    // Even-odd rule in the x–y plane (the contour is a simple polygon seen from the front).
    const Vec3 p = mesh.rest_positions_m[v];
    bool inside = false;
    constexpr std::size_t kCount = std::size(kOuterLip);
    for (std::size_t k = 0, prev = kCount - 1; k < kCount; prev = k++) {
      const Vec3 a = mesh.rest_positions_m[kOuterLip[k]], b = mesh.rest_positions_m[kOuterLip[prev]];
      if ((a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x) inside = !inside;
    }
    if (inside && p.z > mesh.mouth_centre_m.z - 0.01) colours[v] = kLip;
  }
  return colours;
}

void sample_track(const Track& track, std::int64_t t_us, std::span<float> out) {
  const std::size_t c = track.channel_count;
  if (track.frame_count() == 0) {
    std::fill(out.begin(), out.end(), 0.0F);
    return;
  }
  const auto it = std::upper_bound(track.t_us.begin(), track.t_us.end(), t_us);
  if (it == track.t_us.begin() || it == track.t_us.end()) {
    const auto values = track.frame_values(it == track.t_us.begin() ? 0 : track.frame_count() - 1);
    std::copy(values.begin(), values.end(), out.begin());
    return;
  }
  const auto k = static_cast<std::size_t>(it - track.t_us.begin());  // t_us[k-1] <= t < t_us[k]
  const double a =
      static_cast<double>(t_us - track.t_us[k - 1]) / static_cast<double>(track.t_us[k] - track.t_us[k - 1]);
  const auto v0 = track.frame_values(k - 1), v1 = track.frame_values(k);
  for (std::size_t i = 0; i < c; ++i)
    out[i] = static_cast<float>((1.0 - a) * static_cast<double>(v0[i]) + a * static_cast<double>(v1[i]));
}

FaceAnimation simulate_face_animation(const FaceMesh& mesh, const FaceRig& rig, const Track& track, int fps,
                                      FaceSolverParams params) {
  checked_fps(fps, "simulate_face_animation: fps");
  if (track.channel_count != rig.channel_count())
    throw std::invalid_argument("simulate_face_animation: the track's channels are not the rig's model's");
  const int substeps = (30 + fps - 1) / fps;  // the solver's step: 1/fps, or 1/30 s at most
  params.time_step_s = 1.0 / (static_cast<double>(fps) * substeps);
  FaceSolver solver(mesh, rig, params);
  FaceAnimation animation;
  animation.vertex_count = mesh.vertex_count();
  const std::int64_t end_us = track.frame_count() ? track.t_us.back() : 0;
  const auto frame_time = [&](std::int64_t k) {
    return static_cast<std::int64_t>(std::llround(static_cast<double>(k) * 1e6 / fps));
  };
  std::vector<float> channels(track.channel_count, 0.0F);
  // Start at rest, settled for 0.5 s on the first frame's values (a track starts in its rest pose).
  sample_track(track, frame_time(0), channels);
  solver.step(channels, 0.5);
  for (std::int64_t k = 0; k == 0 || frame_time(k - 1) < end_us; ++k) {
    if (k > 0) {
      for (int s = 1; s <= substeps; ++s) {
        const double t_s = (static_cast<double>(k - 1) + static_cast<double>(s) / substeps) / fps;
        sample_track(track, static_cast<std::int64_t>(std::llround(t_s * 1e6)), channels);
        solver.step(channels, params.time_step_s);
      }
    }
    animation.t_us.push_back(frame_time(k));
    const auto x = solver.positions();
    animation.positions.insert(animation.positions.end(), x.begin(), x.end());
  }
  return animation;
}

std::span<const Vec3> FaceTrackStepper::step(std::int64_t t_us, std::span<const float> channel_values) {
  solver_.step(channel_values, static_cast<double>(t_us - previous_t_us_) * 1e-6);
  previous_t_us_ = t_us;
  return solver_.positions();
}

FaceAnimation simulate_track_frames(const FaceMesh& mesh, const FaceRig& rig, const Track& track,
                                    const FaceSolverParams& params) {
  if (track.channel_count != rig.channel_count())
    throw std::invalid_argument("simulate_track_frames: the track's channels are not the rig's model's");
  FaceSolver solver(mesh, rig, params);
  FaceTrackStepper stepper(solver);
  FaceAnimation animation;
  animation.vertex_count = mesh.vertex_count();
  animation.t_us = track.t_us;
  animation.positions.reserve(track.frame_count() * mesh.vertex_count());
  for (std::size_t frame = 0; frame < track.frame_count(); ++frame) {
    const auto x = stepper.step(track.t_us[frame], track.frame_values(frame));
    animation.positions.insert(animation.positions.end(), x.begin(), x.end());
  }
  return animation;
}

FaceAnimation resample_face_animation(const FaceAnimation& animation, int fps) {
  checked_fps(fps, "resample_face_animation: fps");
  if (animation.frame_count() == 0) throw std::invalid_argument("resample_face_animation: the animation has no frames");
  const std::size_t nv = animation.vertex_count;
  const std::int64_t end_us = animation.t_us.back();
  const auto frame_time = [&](std::int64_t k) {
    return static_cast<std::int64_t>(std::llround(static_cast<double>(k) * 1e6 / fps));
  };
  FaceAnimation out;
  out.vertex_count = nv;
  std::size_t next = 0;  // the first frame after t
  for (std::int64_t k = 0; k == 0 || frame_time(k - 1) < end_us; ++k) {
    const std::int64_t t_us = frame_time(k);
    while (next < animation.frame_count() && animation.t_us[next] <= t_us) ++next;
    out.t_us.push_back(t_us);
    if (next == 0 || next == animation.frame_count() || animation.t_us[next - 1] == t_us) {
      const auto pose = animation.frame(next == 0 ? 0 : next - 1);
      out.positions.insert(out.positions.end(), pose.begin(), pose.end());
      continue;
    }
    const auto p0 = animation.frame(next - 1), p1 = animation.frame(next);
    const double a = static_cast<double>(t_us - animation.t_us[next - 1]) /
                     static_cast<double>(animation.t_us[next] - animation.t_us[next - 1]);
    for (std::size_t v = 0; v < nv; ++v) {
      out.positions.push_back(
          {p0[v].x + a * (p1[v].x - p0[v].x), p0[v].y + a * (p1[v].y - p0[v].y), p0[v].z + a * (p1[v].z - p0[v].z)});
    }
  }
  return out;
}

namespace {

// Greedy key selection: from the last key, extend the span as far as every intermediate frame is
// within `tolerance` of the linear interpolation between the span's ends.
std::vector<std::size_t> choose_keys(const FaceAnimation& animation, double tolerance) {
  const std::size_t frames = animation.frame_count();
  std::vector<std::size_t> keys{0};
  if (frames == 1) return keys;
  const auto fits = [&](std::size_t a, std::size_t b) {
    const auto pa = animation.frame(a), pb = animation.frame(b);
    const double ta = static_cast<double>(animation.t_us[a]), tb = static_cast<double>(animation.t_us[b]);
    const double tol2 = tolerance * tolerance;
    for (std::size_t k = a + 1; k < b; ++k) {
      const double w = (static_cast<double>(animation.t_us[k]) - ta) / (tb - ta);
      const auto pk = animation.frame(k);
      for (std::size_t v = 0; v < animation.vertex_count; ++v) {
        const double dx = pk[v].x - (pa[v].x + w * (pb[v].x - pa[v].x));
        const double dy = pk[v].y - (pa[v].y + w * (pb[v].y - pa[v].y));
        const double dz = pk[v].z - (pa[v].z + w * (pb[v].z - pa[v].z));
        if (dx * dx + dy * dy + dz * dz > tol2) return false;
      }
    }
    return true;
  };
  std::size_t last = 0;
  while (last + 1 < frames) {
    std::size_t next = last + 1;
    if (tolerance > 0)
      while (next + 1 < frames && fits(last, next + 1)) ++next;
    keys.push_back(next);
    last = next;
  }
  return keys;
}

class BinaryBuffer {
 public:
  // Appends floats/uints, returns the byte offset (always 4-byte aligned).
  template <typename T>
  std::size_t append(std::span<const T> values) {
    static_assert(sizeof(T) == 4);
    const std::size_t offset = bytes_.size();
    bytes_.resize(offset + values.size_bytes());
    std::memcpy(bytes_.data() + offset, values.data(), values.size_bytes());
    return offset;
  }
  const std::vector<char>& bytes() const { return bytes_; }

 private:
  std::vector<char> bytes_;
};

void write_u32(std::ostream& out, std::uint32_t v) {
  const unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8),
                              static_cast<unsigned char>(v >> 16), static_cast<unsigned char>(v >> 24)};
  out.write(reinterpret_cast<const char*>(b), 4);
}

}  // namespace

GlbSummary write_face_glb(std::ostream& out, const FaceMesh& mesh, const FaceAnimation& animation,
                          const GlbOptions& options) {
  if (animation.frame_count() == 0) throw std::invalid_argument("write_face_glb: the animation has no frames");
  if (animation.vertex_count != mesh.vertex_count() ||
      animation.positions.size() != animation.frame_count() * animation.vertex_count)
    throw std::invalid_argument("write_face_glb: the animation's vertex count is not the mesh's");
  const std::size_t nv = mesh.vertex_count();
  const std::vector<std::size_t> keys = choose_keys(animation, options.key_tolerance_m);

  BinaryBuffer buffer;
  nlohmann::json views = nlohmann::json::array(), accessors = nlohmann::json::array();
  const auto add_view = [&](std::size_t offset, std::size_t length, int target) {
    nlohmann::json view{{"buffer", 0}, {"byteOffset", offset}, {"byteLength", length}};
    if (target) view["target"] = target;
    views.push_back(view);
    return views.size() - 1;
  };
  const auto add_accessor = [&](std::size_t view, int component_type, std::size_t count, const char* type) {
    accessors.push_back({{"bufferView", view}, {"componentType", component_type}, {"count", count}, {"type", type}});
    return accessors.size() - 1;
  };
  constexpr int kFloat = 5126, kUnsignedInt = 5125, kArrayBuffer = 34962, kElementArrayBuffer = 34963;

  std::vector<std::uint32_t> indices;
  indices.reserve(3 * mesh.triangles.size());
  for (const auto& t : mesh.triangles) indices.insert(indices.end(), t.begin(), t.end());
  const std::size_t index_accessor =
      add_accessor(add_view(buffer.append<std::uint32_t>(indices), indices.size() * 4, kElementArrayBuffer),
                   kUnsignedInt, indices.size(), "SCALAR");

  // A float VEC3 attribute with its min and max (required for POSITION, also for morph targets).
  const auto add_vec3 = [&](const std::vector<float>& values) {
    std::array<float, 3> lo{std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                            std::numeric_limits<float>::max()};
    std::array<float, 3> hi{-lo[0], -lo[1], -lo[2]};
    for (std::size_t k = 0; k < values.size(); ++k) {
      lo[k % 3] = std::min(lo[k % 3], values[k]);
      hi[k % 3] = std::max(hi[k % 3], values[k]);
    }
    const std::size_t accessor = add_accessor(add_view(buffer.append<float>(values), values.size() * 4, kArrayBuffer),
                                              kFloat, values.size() / 3, "VEC3");
    accessors[accessor]["min"] = lo;
    accessors[accessor]["max"] = hi;
    return accessor;
  };
  const auto base = animation.frame(0);
  std::vector<float> floats;
  for (const Vec3& p : base)
    floats.insert(floats.end(), {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)});
  const std::size_t position_accessor = add_vec3(floats);
  floats.clear();
  for (const auto& uv : mesh.uvs) floats.insert(floats.end(), {uv[0], uv[1]});
  const std::size_t uv_accessor =
      add_accessor(add_view(buffer.append<float>(floats), floats.size() * 4, kArrayBuffer), kFloat, nv, "VEC2");
  floats.clear();
  for (const auto& c : vertex_colours(mesh)) floats.insert(floats.end(), c.begin(), c.end());
  const std::size_t colour_accessor =
      add_accessor(add_view(buffer.append<float>(floats), floats.size() * 4, kArrayBuffer), kFloat, nv, "VEC3");

  nlohmann::json targets = nlohmann::json::array();
  for (const std::size_t key : keys) {
    floats.clear();
    const auto p = animation.frame(key);
    for (std::size_t v = 0; v < nv; ++v)
      floats.insert(floats.end(), {static_cast<float>(p[v].x - base[v].x), static_cast<float>(p[v].y - base[v].y),
                                   static_cast<float>(p[v].z - base[v].z)});
    targets.push_back({{"POSITION", add_vec3(floats)}});
  }

  // Key times in seconds relative to the first frame; weights one-hot per key.
  std::vector<float> times;
  times.reserve(keys.size());
  for (const std::size_t key : keys)
    times.push_back(static_cast<float>(static_cast<double>(animation.t_us[key] - animation.t_us[0]) * 1e-6));
  const std::size_t time_accessor =
      add_accessor(add_view(buffer.append<float>(times), times.size() * 4, 0), kFloat, times.size(), "SCALAR");
  accessors[time_accessor]["min"] = {times.front()};
  accessors[time_accessor]["max"] = {times.back()};
  std::vector<float> weights(keys.size() * keys.size(), 0.0F);
  for (std::size_t k = 0; k < keys.size(); ++k) weights[k * keys.size() + k] = 1.0F;
  const std::size_t weight_accessor =
      add_accessor(add_view(buffer.append<float>(weights), weights.size() * 4, 0), kFloat, weights.size(), "SCALAR");

  nlohmann::json gltf;
  gltf["asset"] = {{"version", "2.0"}, {"generator", "lipsync"}};
  gltf["scene"] = 0;
  gltf["scenes"] = {{{"nodes", {0}}}};
  gltf["nodes"] = {{{"mesh", 0}, {"name", options.name}}};
  gltf["materials"] = {
      {{"name", "face"},
       {"pbrMetallicRoughness",
        {{"baseColorFactor", {1.0, 1.0, 1.0, 1.0}}, {"metallicFactor", 0.0}, {"roughnessFactor", 0.7}}},
       {"doubleSided", true}}};
  nlohmann::json primitive{
      {"attributes", {{"POSITION", position_accessor}, {"TEXCOORD_0", uv_accessor}, {"COLOR_0", colour_accessor}}},
      {"indices", index_accessor},
      {"material", 0},
      {"mode", 4},
      {"targets", targets}};
  std::vector<float> default_weights(keys.size(), 0.0F);
  default_weights[0] = 1.0F;
  gltf["meshes"] = {{{"name", options.name}, {"primitives", {primitive}}, {"weights", default_weights}}};
  nlohmann::json sampler{{"input", time_accessor}, {"output", weight_accessor}, {"interpolation", "LINEAR"}};
  nlohmann::json channel{{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}};
  nlohmann::json animation_json{{"name", "speech"}};
  animation_json["samplers"] = nlohmann::json::array({sampler});
  animation_json["channels"] = nlohmann::json::array({channel});
  gltf["animations"] = nlohmann::json::array({animation_json});
  gltf["bufferViews"] = views;
  gltf["accessors"] = accessors;
  gltf["buffers"] = {{{"byteLength", buffer.bytes().size()}}};

  std::string json_text = gltf.dump();
  json_text.append((4 - json_text.size() % 4) % 4, ' ');
  const std::size_t bin_length = buffer.bytes().size();  // already a multiple of 4
  const std::size_t total = 12 + 8 + json_text.size() + 8 + bin_length;
  if (total > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("write_face_glb: the animation is too long for one glTF binary (4 GiB)");
  write_u32(out, 0x46546C67U);  // "glTF"
  write_u32(out, 2);
  write_u32(out, static_cast<std::uint32_t>(total));
  write_u32(out, static_cast<std::uint32_t>(json_text.size()));
  write_u32(out, 0x4E4F534AU);  // "JSON"
  out.write(json_text.data(), static_cast<std::streamsize>(json_text.size()));
  write_u32(out, static_cast<std::uint32_t>(bin_length));
  write_u32(out, 0x004E4942U);  // "BIN\0"
  out.write(buffer.bytes().data(), static_cast<std::streamsize>(bin_length));
  return {keys.size(), total};
}

}  // namespace lipsync::face
