// The physics face's eyes: open eyeballs behind the lids, seen from the front at rest (preview and
// glb colours), and blinks from a seeded schedule (docs/face.md, "Eyes"): deterministic for a
// seed, at a natural rate, shutting the upper lid onto the lower one, and none when turned off.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <vector>

#include "lipsync/face/face_animation.hpp"
#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_raster.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/model.hpp"

namespace lipsync::face {
namespace {

const FaceMesh& level1() {
  static const FaceMesh mesh = build_face_mesh(FaceAsset::builtin(), 1);
  return mesh;
}

// Silence held for `seconds`, one frame per 1/30 s.
Track silence(double seconds) {
  const auto& model = ArticulationModel::builtin();
  const auto& sil = model.phoneme(*model.find_phoneme("sil"));
  Track track;
  track.channel_count = model.channel_count();
  for (int k = 0; k <= static_cast<int>(seconds * 30); ++k) {
    track.t_us.push_back(static_cast<std::int64_t>(std::llround(k * 1e6 / 30)));
    track.kinds.push_back(FrameKind{});
    track.values.insert(track.values.end(), sil.targets.begin(), sil.targets.end());
  }
  return track;
}

std::size_t count_parts(const FaceMesh& mesh, FacePart part) {
  return static_cast<std::size_t>(std::count(mesh.parts.begin(), mesh.parts.end(), part));
}

// Pixels of `part` in the preview of `pose`: every other part is drawn in the cavity's dark red
// and `part` in the teeth's white, so a light pixel is a visible one.
std::size_t visible_pixels(const FaceMesh& mesh, std::span<const Vec3> pose, FacePart part) {
  FaceMesh marked = mesh;
  for (auto& p : marked.parts) p = p == part ? FacePart::upper_teeth : FacePart::mouth_cavity;
  std::vector<std::uint8_t> rgb;
  render_face_rgb(marked, pose, RasterOptions{}, rgb);
  std::size_t n = 0;
  for (std::size_t p = 0; p < rgb.size(); p += 3) n += rgb[p + 1] > 120 ? 1 : 0;
  return n;
}

TEST(FaceEyes, EyesAreOpenBehindTheLidsAndSeenFromTheFrontAtRest) {
  const FaceMesh& mesh = level1();
  EXPECT_GT(count_parts(mesh, FacePart::eye_white), 0U);
  EXPECT_GT(count_parts(mesh, FacePart::iris), 0U);
  EXPECT_GT(count_parts(mesh, FacePart::pupil), 0U);
  // The lids are open: no triangle joins three vertices of one eye contour.
  for (const auto& contour : kEyeContours)
    for (const auto& t : mesh.triangles) {
      const auto on = [&](std::uint32_t v) { return std::find(contour.begin(), contour.end(), v) != contour.end(); };
      EXPECT_FALSE(on(t[0]) && on(t[1]) && on(t[2]));
    }
  const std::size_t white = visible_pixels(mesh, mesh.rest_positions_m, FacePart::eye_white);
  const std::size_t iris = visible_pixels(mesh, mesh.rest_positions_m, FacePart::iris);
  const std::size_t pupil = visible_pixels(mesh, mesh.rest_positions_m, FacePart::pupil);
  std::printf("[ measured ] at rest, seen from the front: %zu eye-white, %zu iris, %zu pupil pixels of 480 x 480\n",
              white, iris, pupil);
  EXPECT_GT(white, 200U);
  EXPECT_GT(iris, 200U);
  EXPECT_GT(pupil, 20U);
  // The glb carries them in its vertex colours (COLOR_0 per part).
  const auto colours = vertex_colours(mesh);
  EXPECT_EQ(colours[mesh.eyes_begin], part_colour(mesh.parts[mesh.eyes_begin]));
}

TEST(FaceEyes, TheBlinkScheduleIsDeterministicForASeedAndNatural) {
  const BlinkSettings seed1{.enabled = true, .seed = 1}, seed2{.enabled = true, .seed = 2};
  std::vector<double> a, again, other;
  int blinks = 0;
  bool shut = false;
  double max_closure = 0;
  for (std::int64_t t = 0; t <= 60'000'000; t += 10'000) {
    a.push_back(eyelid_closure(seed1, t));
    again.push_back(eyelid_closure(seed1, t));
    other.push_back(eyelid_closure(seed2, t));
    if (a.back() > 0.5 && !shut) ++blinks;
    shut = a.back() > 0.5;
    max_closure = std::max(max_closure, a.back());
  }
  std::printf("[ measured ] seed 1: %d blinks in the first minute\n", blinks);
  EXPECT_EQ(a, again);
  EXPECT_NE(a, other);
  EXPECT_GE(blinks, 12);  // people blink 12 to 20 times a minute at rest, more when they talk
  EXPECT_LE(blinks, 24);
  EXPECT_EQ(max_closure, 1.0);
  EXPECT_EQ(eyelid_closure(seed1, 0), 0.0);  // open on the first frame
  EXPECT_EQ(eyelid_closure(seed1, kBlinkFirstUs + kBlinkCloseUs), 1.0);
}

TEST(FaceEyes, ABlinkShutsTheUpperLidOnTheLowerAndNoBlinksLeaveTheEyesOpen) {
  const FaceMesh& mesh = level1();
  const Track track = silence(1.5);  // the first blink is shut at 1.08–1.12 s
  const FaceAnimation blinking = simulate_track_frames(mesh, FaceRig::builtin(), track);
  const FaceAnimation still = simulate_track_frames(mesh, FaceRig::builtin(), track, {}, {.enabled = false});
  const std::size_t shut = 33;  // 1.1 s
  ASSERT_EQ(eyelid_closure({}, blinking.t_us[shut]), 1.0);
  for (const auto& [upper, lower] : {std::pair{159U, 145U}, std::pair{386U, 374U}}) {
    const double open_m = still.frame(shut)[upper].y - still.frame(shut)[lower].y;
    const double shut_m = blinking.frame(shut)[upper].y - blinking.frame(shut)[lower].y;
    std::printf("[ measured ] lids %u/%u: %.2f mm apart open, %.2f mm in a blink\n", upper, lower, 1000 * open_m,
                1000 * shut_m);
    EXPECT_GT(open_m, 0.004);
    EXPECT_LT(shut_m, 0.0);  // the shut upper lid overlaps the lower one
  }
  EXPECT_LT(visible_pixels(mesh, blinking.frame(shut), FacePart::iris), 20U);
  // Without blinks every frame is the solver's own pose: the lids never move.
  for (std::size_t k = 0; k < still.frame_count(); ++k)
    EXPECT_DOUBLE_EQ(still.frame(k)[159].y, still.frame(0)[159].y) << "frame " << k;
  // Outside a blink the two are the same pose.
  for (std::size_t v = 0; v < mesh.vertex_count(); ++v) EXPECT_EQ(blinking.frame(10)[v].y, still.frame(10)[v].y);
}

}  // namespace
}  // namespace lipsync::face
