// The render plan: defaults, the range of each field and its one error text.
#include "lipsync/render_plan.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "lipsync/face/face_mesh.hpp"
#include "test_model.hpp"

namespace lipsync {
namespace {

using testing::test_model;

/// The error text resolve_render_plan gives for `settings` ("" if none).
std::string error_of(const RenderSettings& settings, const SettingNames& names = {}) {
  try {
    resolve_render_plan(settings, names);
  } catch (const SettingError& error) {
    return error.what();
  }
  return "";
}

TEST(RenderPlan, UnsetSettingsTakeTheEngineDefaults) {
  const RenderPlan plan = resolve_render_plan({});
  EXPECT_EQ(plan.render.fps, 30);
  EXPECT_FALSE(plan.render.fixed_rate);
  EXPECT_EQ(plan.render.lookahead, 7);
  EXPECT_EQ(plan.segments.closure_fraction, 0.6);
  EXPECT_EQ(plan.mesh_subdivision, 1);
  // The engine's own option structs default to the same values.
  EXPECT_EQ(plan.render.fps, RenderOptions{}.fps);
  EXPECT_EQ(plan.render.lookahead, RenderOptions{}.lookahead);
  EXPECT_EQ(plan.segments.closure_fraction, SegmentOptions{}.closure_fraction);
}

TEST(RenderPlan, GivenSettingsPassThroughUnchanged) {
  const RenderPlan plan = resolve_render_plan(
      {.fps = 240, .fixed_rate = true, .lookahead = 0, .closure_fraction = 0.95, .mesh_subdivision = 2});
  EXPECT_EQ(plan.render.fps, 240);
  EXPECT_TRUE(plan.render.fixed_rate);
  EXPECT_EQ(plan.render.lookahead, 0);
  EXPECT_EQ(plan.segments.closure_fraction, 0.95);
  EXPECT_EQ(plan.mesh_subdivision, 2);
}

TEST(RenderPlan, FpsIs1To240) {
  EXPECT_EQ(error_of({.fps = 1}), "");
  EXPECT_EQ(error_of({.fps = 240}), "");
  EXPECT_EQ(error_of({.fps = 0}), "fps: '0' is out of range (1 to 240, default 30)");
  EXPECT_EQ(error_of({.fps = 241}), "fps: '241' is out of range (1 to 240, default 30)");
  EXPECT_EQ(error_of({.fps = -3}), "fps: '-3' is out of range (1 to 240, default 30)");
}

TEST(RenderPlan, LookaheadIs0To7) {
  EXPECT_EQ(error_of({.lookahead = 0}), "");
  EXPECT_EQ(error_of({.lookahead = 7}), "");
  EXPECT_EQ(error_of({.lookahead = 8}), "lookahead: '8' is out of range (0 to 7, default 7)");
  EXPECT_EQ(error_of({.lookahead = -1}), "lookahead: '-1' is out of range (0 to 7, default 7)");
}

TEST(RenderPlan, ClosureFractionLiesStrictlyBetween0And1) {
  EXPECT_EQ(error_of({.closure_fraction = 0.001}), "");
  EXPECT_EQ(error_of({.closure_fraction = 0.999}), "");
  const std::string range = " is out of range (strictly between 0 and 1, default 0.6)";
  EXPECT_EQ(error_of({.closure_fraction = 0.0}), "closure_fraction: '0'" + range);
  EXPECT_EQ(error_of({.closure_fraction = 1.0}), "closure_fraction: '1'" + range);
  EXPECT_EQ(error_of({.closure_fraction = 1.5}), "closure_fraction: '1.5'" + range);
  EXPECT_EQ(error_of({.closure_fraction = -0.25}), "closure_fraction: '-0.25'" + range);
  EXPECT_EQ(error_of({.closure_fraction = std::numeric_limits<double>::quiet_NaN()}),
            "closure_fraction: 'nan'" + range);
}

TEST(RenderPlan, MeshSubdivisionIs0To2) {
  EXPECT_EQ(error_of({.mesh_subdivision = 0}), "");
  EXPECT_EQ(error_of({.mesh_subdivision = 2}), "");
  EXPECT_EQ(error_of({.mesh_subdivision = 3}), "mesh_subdivision: '3' is out of range (0 to 2, default 1)");
  EXPECT_EQ(error_of({.mesh_subdivision = -1}), "mesh_subdivision: '-1' is out of range (0 to 2, default 1)");
}

TEST(RenderPlan, ErrorsNameTheFieldAsTheCallerSpellsIt) {
  const SettingNames wire = {.fps = "settings.fps",
                             .lookahead = "settings.lookahead",
                             .closure_fraction = "settings.closure_fraction",
                             .mesh_subdivision = "settings.outputs.mesh.subdivision"};
  EXPECT_EQ(error_of({.fps = 241}, wire), "settings.fps: '241' is out of range (1 to 240, default 30)");
  EXPECT_EQ(error_of({.lookahead = 8}, wire), "settings.lookahead: '8' is out of range (0 to 7, default 7)");
  EXPECT_THAT(error_of({.closure_fraction = 1.5}, wire), ::testing::StartsWith("settings.closure_fraction: '1.5'"));
  EXPECT_THAT(error_of({.mesh_subdivision = 3}, wire), ::testing::StartsWith("settings.outputs.mesh.subdivision: '3'"));
  try {
    resolve_render_plan({.lookahead = 9}, wire);
    FAIL() << "no error";
  } catch (const SettingError& error) {
    EXPECT_EQ(error.field(), "settings.lookahead");
  }
}

TEST(RenderPlan, TheFirstBadFieldIsReported) {
  EXPECT_THAT(error_of({.fps = 0, .lookahead = 8}), ::testing::StartsWith("fps:"));
  EXPECT_THAT(error_of({.lookahead = 8, .closure_fraction = 2.0}), ::testing::StartsWith("lookahead:"));
}

TEST(RenderPlan, EngineConstructorsRejectWhatThePlanRejectsWithTheSameText) {
  EXPECT_THROW(FrameScheduler(test_model(), {.fps = 241}), SettingError);
  EXPECT_THROW(StreamingRenderer(test_model(), {.lookahead = 8}), SettingError);
  EXPECT_THROW(face::build_face_mesh(face::FaceAsset::builtin(), 3), SettingError);
  try {
    StreamingRenderer(test_model(), {.fps = 0});
    FAIL() << "no error";
  } catch (const SettingError& error) {
    EXPECT_STREQ(error.what(), "fps: '0' is out of range (1 to 240, default 30)");
  }
}

}  // namespace
}  // namespace lipsync
