// Simulated poses → glTF binary (write_face_glb); the design is in face_animation.hpp and
// docs/face.md. The writer picks the key frames (choose_keys), lays the mesh, one morph target
// per key and the key animation into one binary buffer with their views and accessors
// (GltfBuffers), describes them in the glTF JSON document (gltf_document) and writes both as the
// GLB container (write_glb).
//
// GLB layout: a 12-byte header, a JSON chunk (padded with spaces) and a BIN chunk (padded with
// zeros). The BIN chunk holds, 4-byte aligned and in this order: triangle indices (uint32), base
// positions (float VEC3, the first frame), UVs (float VEC2), colours (float VEC3), one displacement
// per key frame (float VEC3, key − base), key times (float seconds) and the one-hot weights
// (float, keys × keys).
#include <algorithm>
#include <array>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "lipsync/face/face_animation.hpp"

namespace lipsync::face {

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

constexpr int kFloat = 5126, kUnsignedInt = 5125, kArrayBuffer = 34962, kElementArrayBuffer = 34963;

// The binary buffer with the glTF buffer views and accessors that describe its parts, in the
// order they were added.
class GltfBuffers {
 public:
  std::size_t add_view(std::size_t offset, std::size_t length, int target) {
    nlohmann::json view{{"buffer", 0}, {"byteOffset", offset}, {"byteLength", length}};
    if (target) view["target"] = target;
    views_.push_back(view);
    return views_.size() - 1;
  }
  std::size_t add_accessor(std::size_t view, int component_type, std::size_t count, const char* type) {
    accessors_.push_back({{"bufferView", view}, {"componentType", component_type}, {"count", count}, {"type", type}});
    return accessors_.size() - 1;
  }
  // Appends `values` in a view of their own with one accessor over them.
  template <typename T>
  std::size_t add(const std::vector<T>& values, int target, int component_type, std::size_t count, const char* type) {
    return add_accessor(add_view(buffer_.append<T>(values), values.size() * 4, target), component_type, count, type);
  }
  // A float VEC3 attribute with its min and max (required for POSITION, also for morph targets).
  std::size_t add_vec3(const std::vector<float>& values) {
    std::array<float, 3> lo{std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                            std::numeric_limits<float>::max()};
    std::array<float, 3> hi{-lo[0], -lo[1], -lo[2]};
    for (std::size_t k = 0; k < values.size(); ++k) {
      lo[k % 3] = std::min(lo[k % 3], values[k]);
      hi[k % 3] = std::max(hi[k % 3], values[k]);
    }
    const std::size_t accessor = add(values, kArrayBuffer, kFloat, values.size() / 3, "VEC3");
    accessors_[accessor]["min"] = lo;
    accessors_[accessor]["max"] = hi;
    return accessor;
  }
  nlohmann::json& accessor(std::size_t index) { return accessors_[index]; }

  const nlohmann::json& views() const { return views_; }
  const nlohmann::json& accessors() const { return accessors_; }
  const std::vector<char>& bytes() const { return buffer_.bytes(); }

 private:
  BinaryBuffer buffer_;
  nlohmann::json views_ = nlohmann::json::array(), accessors_ = nlohmann::json::array();
};

// The accessors of the mesh's primitive and of its animation.
struct MeshAccessors {
  std::size_t indices = 0, position = 0, uv = 0, colour = 0;
};
struct KeyAccessors {
  std::size_t time = 0, weight = 0;
};

// The mesh once: triangle indices, base positions (the first frame), UVs and colours.
MeshAccessors add_mesh(GltfBuffers& buffers, const FaceMesh& mesh, std::span<const Vec3> base) {
  const std::size_t nv = mesh.vertex_count();
  MeshAccessors out;
  std::vector<std::uint32_t> indices;
  indices.reserve(3 * mesh.triangles.size());
  for (const auto& t : mesh.triangles) indices.insert(indices.end(), t.begin(), t.end());
  out.indices = buffers.add(indices, kElementArrayBuffer, kUnsignedInt, indices.size(), "SCALAR");
  std::vector<float> floats;
  for (const Vec3& p : base)
    floats.insert(floats.end(), {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)});
  out.position = buffers.add_vec3(floats);
  floats.clear();
  for (const auto& uv : mesh.uvs) floats.insert(floats.end(), {uv[0], uv[1]});
  out.uv = buffers.add(floats, kArrayBuffer, kFloat, nv, "VEC2");
  floats.clear();
  for (const auto& c : vertex_colours(mesh)) floats.insert(floats.end(), c.begin(), c.end());
  out.colour = buffers.add(floats, kArrayBuffer, kFloat, nv, "VEC3");
  return out;
}

// One morph target per key frame: its displacement from the base positions.
nlohmann::json add_morph_targets(GltfBuffers& buffers, const FaceAnimation& animation,
                                 const std::vector<std::size_t>& keys) {
  const std::size_t nv = animation.vertex_count;
  const auto base = animation.frame(0);
  nlohmann::json targets = nlohmann::json::array();
  std::vector<float> floats;
  for (const std::size_t key : keys) {
    floats.clear();
    const auto p = animation.frame(key);
    for (std::size_t v = 0; v < nv; ++v)
      floats.insert(floats.end(), {static_cast<float>(p[v].x - base[v].x), static_cast<float>(p[v].y - base[v].y),
                                   static_cast<float>(p[v].z - base[v].z)});
    targets.push_back({{"POSITION", buffers.add_vec3(floats)}});
  }
  return targets;
}

// Key times in seconds relative to the first frame; weights one-hot per key.
KeyAccessors add_key_animation(GltfBuffers& buffers, const FaceAnimation& animation,
                               const std::vector<std::size_t>& keys) {
  KeyAccessors out;
  std::vector<float> times;
  times.reserve(keys.size());
  for (const std::size_t key : keys)
    times.push_back(static_cast<float>(static_cast<double>(animation.t_us[key] - animation.t_us[0]) * 1e-6));
  out.time = buffers.add(times, 0, kFloat, times.size(), "SCALAR");
  buffers.accessor(out.time)["min"] = {times.front()};
  buffers.accessor(out.time)["max"] = {times.back()};
  std::vector<float> weights(keys.size() * keys.size(), 0.0F);
  for (std::size_t k = 0; k < keys.size(); ++k) weights[k * keys.size() + k] = 1.0F;
  out.weight = buffers.add(weights, 0, kFloat, weights.size(), "SCALAR");
  return out;
}

// The glTF JSON: one scene, one node with the mesh and its morph targets, one material, one
// animation of the node's weights.
nlohmann::json gltf_document(const GltfBuffers& buffers, const MeshAccessors& mesh, nlohmann::json targets,
                             const KeyAccessors& key_animation, std::size_t key_count, const GlbOptions& options) {
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
      {"attributes", {{"POSITION", mesh.position}, {"TEXCOORD_0", mesh.uv}, {"COLOR_0", mesh.colour}}},
      {"indices", mesh.indices},
      {"material", 0},
      {"mode", 4},
      {"targets", std::move(targets)}};
  std::vector<float> default_weights(key_count, 0.0F);
  default_weights[0] = 1.0F;
  gltf["meshes"] = {{{"name", options.name}, {"primitives", {primitive}}, {"weights", default_weights}}};
  nlohmann::json sampler{{"input", key_animation.time}, {"output", key_animation.weight}, {"interpolation", "LINEAR"}};
  nlohmann::json channel{{"sampler", 0}, {"target", {{"node", 0}, {"path", "weights"}}}};
  nlohmann::json animation_json{{"name", "speech"}};
  animation_json["samplers"] = nlohmann::json::array({sampler});
  animation_json["channels"] = nlohmann::json::array({channel});
  gltf["animations"] = nlohmann::json::array({animation_json});
  gltf["bufferViews"] = buffers.views();
  gltf["accessors"] = buffers.accessors();
  gltf["buffers"] = {{{"byteLength", buffers.bytes().size()}}};
  return gltf;
}

void write_u32(std::ostream& out, std::uint32_t v) {
  const unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8),
                              static_cast<unsigned char>(v >> 16), static_cast<unsigned char>(v >> 24)};
  out.write(reinterpret_cast<const char*>(b), 4);
}

// The GLB container: header, JSON chunk, BIN chunk. Returns the bytes written.
std::size_t write_glb(std::ostream& out, std::string json_text, const std::vector<char>& bin) {
  json_text.append((4 - json_text.size() % 4) % 4, ' ');
  const std::size_t bin_length = bin.size();  // already a multiple of 4
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
  out.write(bin.data(), static_cast<std::streamsize>(bin_length));
  return total;
}

}  // namespace

GlbSummary write_face_glb(std::ostream& out, const FaceMesh& mesh, const FaceAnimation& animation,
                          const GlbOptions& options) {
  if (animation.frame_count() == 0) throw std::invalid_argument("write_face_glb: the animation has no frames");
  if (animation.vertex_count != mesh.vertex_count() ||
      animation.positions.size() != animation.frame_count() * animation.vertex_count)
    throw std::invalid_argument("write_face_glb: the animation's vertex count is not the mesh's");
  const std::vector<std::size_t> keys = choose_keys(animation, options.key_tolerance_m);
  GltfBuffers buffers;
  const MeshAccessors mesh_accessors = add_mesh(buffers, mesh, animation.frame(0));
  nlohmann::json targets = add_morph_targets(buffers, animation, keys);
  const KeyAccessors key_accessors = add_key_animation(buffers, animation, keys);
  const nlohmann::json gltf =
      gltf_document(buffers, mesh_accessors, std::move(targets), key_accessors, keys.size(), options);
  const std::size_t total = write_glb(out, gltf.dump(), buffers.bytes());
  return {keys.size(), total};
}

}  // namespace lipsync::face
