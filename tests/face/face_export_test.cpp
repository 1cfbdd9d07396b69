// The face over time: track sampling, simulation on a uniform grid, the glTF binary's structure
// (header, chunks, accessors and buffer views that fit, POSITION min/max that match the data, a
// weights animation whose keys reproduce every simulated frame), the preview rasteriser, and the
// face at rest as a user sees it in those outputs (lips together, upper teeth hidden).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "../support/lip_measures.hpp"
#include "lipsync/face/face_animation.hpp"
#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_raster.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/model.hpp"

namespace lipsync::face {
namespace {

std::vector<float> targets_of(const std::string& phoneme) {
  const auto& model = ArticulationModel::builtin();
  const auto& spec = model.phoneme(*model.find_phoneme(phoneme));
  return {spec.targets.begin(), spec.targets.end()};
}

// A track holding each phoneme's targets for `hold_us`, a frame at the start and end of each hold.
Track held_track(const std::vector<std::string>& phonemes, std::int64_t hold_us) {
  Track track;
  track.channel_count = ArticulationModel::builtin().channel_count();
  std::int64_t t = 0;
  for (const auto& phoneme : phonemes) {
    const auto values = targets_of(phoneme);
    for (const std::int64_t at : {t + 40'000, t + hold_us}) {
      track.t_us.push_back(at);
      track.kinds.push_back(FrameKind{});
      track.values.insert(track.values.end(), values.begin(), values.end());
    }
    t += hold_us;
  }
  track.t_us.front() = 0;
  return track;
}

const FaceMesh& level0() {
  static const FaceMesh mesh = build_face_mesh(FaceAsset::builtin(), 0);
  return mesh;
}

std::uint32_t read_u32(const std::string& bytes, std::size_t offset) {
  std::uint32_t v = 0;
  for (int k = 3; k >= 0; --k) v = (v << 8) | static_cast<unsigned char>(bytes[offset + static_cast<std::size_t>(k)]);
  return v;
}

struct Glb {
  nlohmann::json json;
  std::string bin;
  std::vector<float> floats(std::size_t accessor) const {
    const auto& a = json["accessors"][accessor];
    const auto& view = json["bufferViews"][a["bufferView"].get<std::size_t>()];
    const std::size_t components = a["type"] == "VEC3" ? 3 : a["type"] == "VEC2" ? 2 : 1;
    std::vector<float> out(a["count"].get<std::size_t>() * components);
    std::memcpy(out.data(), bin.data() + view["byteOffset"].get<std::size_t>(), out.size() * 4);
    return out;
  }
};

Glb parse_glb(const std::string& bytes) {
  EXPECT_GE(bytes.size(), 28U);
  EXPECT_EQ(bytes.substr(0, 4), "glTF");
  EXPECT_EQ(read_u32(bytes, 4), 2U);
  EXPECT_EQ(read_u32(bytes, 8), bytes.size());
  const std::uint32_t json_length = read_u32(bytes, 12);
  EXPECT_EQ(bytes.substr(16, 4), "JSON");
  EXPECT_EQ(json_length % 4, 0U);
  Glb glb;
  glb.json = nlohmann::json::parse(bytes.substr(20, json_length));
  const std::size_t bin_at = 20 + json_length;
  const std::uint32_t bin_length = read_u32(bytes, bin_at);
  EXPECT_EQ(bytes.substr(bin_at + 4, 4), std::string("BIN\0", 4));
  EXPECT_EQ(bin_at + 8 + bin_length, bytes.size());
  glb.bin = bytes.substr(bin_at + 8, bin_length);
  return glb;
}

TEST(FaceAnimation, SampleTrackInterpolatesAndHoldsTheEnds) {
  Track track;
  track.channel_count = 1;
  track.t_us = {100, 300};
  track.kinds = {FrameKind{}, FrameKind{}};
  track.values = {1.0F, 3.0F};
  float v = 0;
  sample_track(track, 0, {&v, 1});
  EXPECT_EQ(v, 1.0F);
  sample_track(track, 200, {&v, 1});
  EXPECT_FLOAT_EQ(v, 2.0F);
  sample_track(track, 1000, {&v, 1});
  EXPECT_EQ(v, 3.0F);
}

TEST(FaceAnimation, SimulatesAUniformGridToTheEndOfTheTrack) {
  const Track track = held_track({"sil", "aa", "m"}, 300'000);
  const FaceAnimation animation = simulate_face_animation(level0(), FaceRig::builtin(), track, 30);
  ASSERT_EQ(animation.frame_count(), 28U);  // 0 .. 900 ms at 30 frames/s
  EXPECT_EQ(animation.t_us[1], 33'333);
  EXPECT_EQ(animation.t_us.back(), 900'000);
  EXPECT_EQ(animation.positions.size(), 28 * level0().vertex_count());
  // The mouth is open during /aa/ (frame at 0.5 s) and closed at the end of /m/.
  const auto gap = [&](std::size_t k) { return std::abs(animation.frame(k)[13].y - animation.frame(k)[14].y); };
  EXPECT_GT(gap(15), 0.015);
  EXPECT_LT(gap(27), 0.002);
}

TEST(FaceGlb, HasConsistentAccessorsViewsAndBounds) {
  const Track track = held_track({"sil", "aa", "uw", "m", "sil"}, 250'000);
  const FaceAnimation animation = simulate_face_animation(level0(), FaceRig::builtin(), track, 30);
  std::ostringstream out;
  const GlbSummary summary = write_face_glb(out, level0(), animation);
  const std::string bytes = out.str();
  EXPECT_EQ(summary.bytes, bytes.size());
  const Glb glb = parse_glb(bytes);
  const auto& j = glb.json;
  EXPECT_EQ(j["asset"]["version"], "2.0");
  EXPECT_EQ(j["buffers"][0]["byteLength"].get<std::size_t>(), glb.bin.size());
  for (const auto& view : j["bufferViews"]) {
    EXPECT_EQ(view["byteOffset"].get<std::size_t>() % 4, 0U);
    EXPECT_LE(view["byteOffset"].get<std::size_t>() + view["byteLength"].get<std::size_t>(), glb.bin.size());
  }
  for (const auto& a : j["accessors"]) {
    const std::size_t components = a["type"] == "VEC3" ? 3 : a["type"] == "VEC2" ? 2 : 1;
    const auto& view = j["bufferViews"][a["bufferView"].get<std::size_t>()];
    EXPECT_EQ(a["count"].get<std::size_t>() * components * 4, view["byteLength"].get<std::size_t>());
  }
  const auto& primitive = j["meshes"][0]["primitives"][0];
  const std::size_t nv = level0().vertex_count();
  EXPECT_EQ(j["accessors"][primitive["indices"].get<std::size_t>()]["count"], 3 * level0().triangles.size());
  EXPECT_EQ(j["accessors"][primitive["attributes"]["POSITION"].get<std::size_t>()]["count"], nv);
  EXPECT_EQ(j["accessors"][primitive["attributes"]["TEXCOORD_0"].get<std::size_t>()]["count"], nv);
  // Every POSITION accessor (base and morph targets) has min/max equal to its data's.
  std::vector<std::size_t> positions{primitive["attributes"]["POSITION"].get<std::size_t>()};
  for (const auto& target : primitive["targets"]) positions.push_back(target["POSITION"].get<std::size_t>());
  for (const std::size_t accessor : positions) {
    const auto values = glb.floats(accessor);
    ASSERT_EQ(values.size(), 3 * nv);
    for (std::size_t c = 0; c < 3; ++c) {
      float lo = std::numeric_limits<float>::max(), hi = -lo;
      for (std::size_t v = 0; v < nv; ++v) lo = std::min(lo, values[3 * v + c]), hi = std::max(hi, values[3 * v + c]);
      EXPECT_EQ(j["accessors"][accessor]["min"][c].get<float>(), lo);
      EXPECT_EQ(j["accessors"][accessor]["max"][c].get<float>(), hi);
    }
  }
  // One target per key frame, fewer keys than frames (holds), one-hot LINEAR weights.
  const std::size_t keys = primitive["targets"].size();
  EXPECT_EQ(keys, summary.key_frames);
  EXPECT_LT(keys, animation.frame_count());
  EXPECT_GE(keys, 5U);
  const auto& sampler = j["animations"][0]["samplers"][0];
  EXPECT_EQ(sampler["interpolation"], "LINEAR");
  EXPECT_EQ(j["animations"][0]["channels"][0]["target"]["path"], "weights");
  const auto times = glb.floats(sampler["input"].get<std::size_t>());
  const auto weights = glb.floats(sampler["output"].get<std::size_t>());
  ASSERT_EQ(times.size(), keys);
  ASSERT_EQ(weights.size(), keys * keys);
  EXPECT_EQ(times.front(), 0.0F);
  EXPECT_FLOAT_EQ(times.back(), 38.0F / 30.0F);  // the first grid frame at or after 1.25 s
  for (std::size_t k = 1; k < keys; ++k) EXPECT_LT(times[k - 1], times[k]);
  for (std::size_t k = 0; k < keys; ++k)
    for (std::size_t m = 0; m < keys; ++m) EXPECT_EQ(weights[k * keys + m], k == m ? 1.0F : 0.0F);
  // Playing the animation (linear blend of the two surrounding targets) reproduces every frame.
  const auto base = glb.floats(positions[0]);
  std::vector<std::vector<float>> target(keys);
  for (std::size_t k = 0; k < keys; ++k) target[k] = glb.floats(positions[k + 1]);
  double worst = 0;
  for (std::size_t f = 0; f < animation.frame_count(); ++f) {
    const double t = static_cast<double>(animation.t_us[f]) * 1e-6;
    std::size_t k = 0;
    while (k + 2 < keys && times[k + 1] <= t) ++k;
    const double w = std::clamp((t - times[k]) / (times[k + 1] - times[k]), 0.0, 1.0);
    for (std::size_t v = 0; v < nv; ++v) {
      const double x = base[3 * v] + (1 - w) * target[k][3 * v] + w * target[k + 1][3 * v];
      const double y = base[3 * v + 1] + (1 - w) * target[k][3 * v + 1] + w * target[k + 1][3 * v + 1];
      const double z = base[3 * v + 2] + (1 - w) * target[k][3 * v + 2] + w * target[k + 1][3 * v + 2];
      const Vec3 p = animation.frame(f)[v];
      worst = std::max(worst, std::hypot(x - p.x, y - p.y, z - p.z));
    }
  }
  std::printf("[ measured ] %zu frames, %zu keys, %zu bytes, worst playback error %.4f mm\n", animation.frame_count(),
              keys, bytes.size(), 1000 * worst);
  EXPECT_LT(worst, 0.00011);
}

TEST(FaceGlb, ToleranceZeroKeepsEveryFrame) {
  const FaceAnimation animation =
      simulate_face_animation(level0(), FaceRig::builtin(), held_track({"sil", "aa"}, 100'000), 30);
  std::ostringstream out;
  GlbOptions options;
  options.key_tolerance_m = 0;
  EXPECT_EQ(write_face_glb(out, level0(), animation, options).key_frames, animation.frame_count());
}

// What a user sees of the rest pose: the lips together in the glb (its POSITION is the first frame,
// its last key the face after a second of silence), and no upper tooth in the preview. The teeth
// are found in the picture by rendering a copy of the mesh whose other parts all have the cavity's
// dark red, so any light pixel is a visible tooth; an /aa/ shows some, so the measure can see them.
TEST(FaceRest, TheFaceRestsWithItsLipsTogetherAndItsUpperTeethHidden) {
  const FaceMesh mesh = build_face_mesh(FaceAsset::builtin(), 1);  // the default level
  const FaceAnimation animation = simulate_track_frames(mesh, FaceRig::builtin(), held_track({"sil"}, 1'000'000));
  std::ostringstream out;
  GlbOptions options;
  options.key_tolerance_m = 0.00001;  // as lipsync render --mesh
  write_face_glb(out, mesh, animation, options);
  const Glb glb = parse_glb(out.str());
  const auto& primitive = glb.json["meshes"][0]["primitives"][0];
  const auto base = glb.floats(primitive["attributes"]["POSITION"].get<std::size_t>());
  const auto last = glb.floats(primitive["targets"].back()["POSITION"].get<std::size_t>());
  ASSERT_EQ(base.size(), 3 * mesh.vertex_count());
  std::vector<Vec3> first_pose(mesh.vertex_count()), last_pose(mesh.vertex_count());
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) {
    first_pose[v] = {base[3 * v], base[3 * v + 1], base[3 * v + 2]};
    last_pose[v] = {base[3 * v] + last[3 * v], base[3 * v + 1] + last[3 * v + 1], base[3 * v + 2] + last[3 * v + 2]};
  }
  const double first_gap = lip_gap_m(mesh, first_pose), last_gap = lip_gap_m(mesh, last_pose);

  FaceMesh teeth_only = mesh;
  for (auto& part : teeth_only.parts)
    if (part != FacePart::upper_teeth) part = FacePart::mouth_cavity;
  const auto teeth_pixels = [&](std::span<const Vec3> pose) {
    std::vector<std::uint8_t> rgb;
    render_face_rgb(teeth_only, pose, RasterOptions{}, rgb);
    std::size_t n = 0;
    for (std::size_t p = 0; p < rgb.size(); p += 3) n += rgb[p + 1] > 120 ? 1 : 0;
    return n;
  };
  FaceSolver solver(mesh, FaceRig::builtin());
  const auto aa = targets_of("aa");
  for (int frame = 0; frame < 30; ++frame) solver.step(aa, 1.0 / 30.0);
  const std::size_t at_rest = teeth_pixels(last_pose), at_aa = teeth_pixels(solver.positions());
  std::printf(
      "[ measured ] at rest: lips %.3f mm apart (glb first frame), %.3f mm (after 1 s); %zu upper-teeth "
      "pixels (/aa/: %zu)\n",
      1000 * first_gap, 1000 * last_gap, at_rest, at_aa);
  EXPECT_LE(first_gap, 0.0005);
  EXPECT_LE(last_gap, 0.0005);
  EXPECT_EQ(at_rest, 0U);
  EXPECT_GT(at_aa, 100U);
}

TEST(FaceRaster, DrawsAFaceAndAnOpenMouthShowsTheDarkCavity) {
  const FaceMesh& mesh = level0();
  const FaceAnimation animation =
      simulate_face_animation(mesh, FaceRig::builtin(), held_track({"sil", "aa"}, 400'000), 30);
  RasterOptions options;
  options.width = 160;
  options.height = 160;
  std::vector<std::uint8_t> rest, open;
  render_face_rgb(mesh, animation.frame(0), options, rest);
  render_face_rgb(mesh, animation.frame(animation.frame_count() - 1), options, open);
  ASSERT_EQ(rest.size(), 160U * 160U * 3U);
  const auto count = [&](const std::vector<std::uint8_t>& rgb, auto predicate) {
    std::size_t n = 0;
    for (std::size_t p = 0; p < rgb.size(); p += 3) n += predicate(rgb[p], rgb[p + 1], rgb[p + 2]) ? 1 : 0;
    return n;
  };
  const auto skin = [](int r, int g, int b) { return r > 150 && r > g && g > b; };
  const auto dark_red = [](int r, int g, int b) { return r < 140 && r > 2 * g && r > 2 * b; };
  EXPECT_GT(count(rest, skin), 160U * 160U / 3);
  EXPECT_GT(count(open, dark_red), count(rest, dark_red) + 100);
  std::vector<std::uint8_t> again;
  render_face_rgb(mesh, animation.frame(0), options, again);
  EXPECT_EQ(again, rest);
}

}  // namespace
}  // namespace lipsync::face
