// From what a user asked for to what the engine runs: the one place that turns
// render settings into validated options (ranges: lipsync/setting_ranges.hpp).
//
// A RenderSettings holds the settings as given, each one unset when the user
// said nothing (the server's protobuf zeros and the CLI's absent flags both map
// to "unset"). resolve_render_plan fills in the defaults, checks every range
// and returns the options the segment builder, the renderer and the face take.
// A value out of range throws the SettingError of lipsync/setting_ranges.hpp,
// naming the field as the caller spells it (SettingNames).
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/setting_ranges.hpp"

namespace lipsync {

/// The render settings as a user gives them; unset means the default.
struct RenderSettings {
  std::optional<std::int64_t> fps = std::nullopt;
  bool fixed_rate = false;
  std::optional<std::int64_t> lookahead = std::nullopt;
  std::optional<double> closure_fraction = std::nullopt;
  std::optional<std::int64_t> mesh_subdivision = std::nullopt;
};

/// How the caller names each field in its messages.
struct SettingNames {
  std::string_view fps = "fps";
  std::string_view lookahead = "lookahead";
  std::string_view closure_fraction = "closure_fraction";
  std::string_view mesh_subdivision = "mesh_subdivision";
};

/// The validated options, ready for SegmentBuilder, the renderers and the face.
struct RenderPlan {
  RenderOptions render;
  SegmentOptions segments;
  int mesh_subdivision = static_cast<int>(kMeshSubdivisionSetting.default_value);
};

/// Fills in the defaults and checks every range. Throws SettingError for the
/// first field out of range (in the order of RenderSettings).
RenderPlan resolve_render_plan(const RenderSettings& settings, const SettingNames& names = {});

}  // namespace lipsync
