// The ranges and defaults of the render settings, stated once, and the checks
// that enforce them (one error text per field).
//
// Everything that takes a frame rate, a lookahead, a closure fraction or a mesh
// subdivision level checks it here: resolve_render_plan (lipsync/render_plan.hpp)
// for what a user asked for, and the engine's constructors (FrameScheduler,
// StreamingRenderer, SegmentBuilder) for the options they are given. A value out
// of range throws a SettingError whose text names the field as the caller spells
// it ("settings.fps" on the wire, "--fps" on the command line), the bad value and
// the range with its default:
//   settings.fps: '241' is out of range (1 to 240, default 30)
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace lipsync {

/// A whole-number setting: its range (inclusive) and its default.
struct IntSetting {
  std::int64_t min;
  std::int64_t max;
  std::int64_t default_value;
};

/// Frames per second of the uniform grid.
inline constexpr IntSetting kFpsSetting = {1, 240, 30};
/// Segments after a frame's own that must be known before it is emitted; the
/// maximum (the coarticulation window radius, 7) is exact, fewer approximate.
inline constexpr IntSetting kLookaheadSetting = {0, 7, 7};
/// Subdivision level of the face mesh (1061, 2643 or 8903 vertices).
inline constexpr IntSetting kMeshSubdivisionSetting = {0, 2, 1};
/// Share of a /p b/ segment given to its closure; the range is (0, 1), exclusive.
inline constexpr double kDefaultClosureFraction = 0.6;

/// A setting out of range. what(): "<field>: '<value>' is out of range (<range>, default <d>)".
class SettingError : public std::invalid_argument {
 public:
  SettingError(std::string field, const std::string& message);
  /// The field as the caller named it ("settings.fps", "--fps").
  const std::string& field() const noexcept { return field_; }

 private:
  std::string field_;
};

/// The one wording of a value outside its range, for every check in lipsyncd and lipsync (render
/// settings, command-line options, the server's configuration, Speak's rate):
/// "<field>: '<value>' is out of range (<range>)".
std::string out_of_range_text(std::string_view field, std::string_view value, std::string_view range);
/// The same without the field: "'<value>' is out of range (<range>)".
std::string out_of_range_message(std::string_view value, std::string_view range);
/// "<min> to <max>", and ", default <d>" after it when `with_default`.
std::string range_text(const IntSetting& setting, bool with_default = true);

/// Each returns the value if it is in range, else throws SettingError naming `field`.
int checked_fps(std::int64_t fps, std::string_view field);
int checked_lookahead(std::int64_t lookahead, std::string_view field);
double checked_closure_fraction(double fraction, std::string_view field);
int checked_mesh_subdivision(std::int64_t level, std::string_view field);

}  // namespace lipsync
