// Defaults and ranges of the render settings, and their one error text
// (lipsync/render_plan.hpp). Numbers are written back in their shortest exact
// form, so a message shows the value the user typed ('0.95', not 0.950000).
#include "lipsync/render_plan.hpp"

#include <array>
#include <charconv>

namespace lipsync {
namespace {

std::string shortest(double value) {
  std::array<char, 32> text{};
  const auto result = std::to_chars(text.data(), text.data() + text.size(), value);
  return std::string(text.data(), result.ptr);
}

[[noreturn]] void out_of_range(std::string_view field, const std::string& value, const std::string& range) {
  throw SettingError(std::string(field), out_of_range_message(value, range));
}

int checked_int(std::int64_t value, const IntSetting& setting, std::string_view field) {
  if (value < setting.min || value > setting.max) out_of_range(field, std::to_string(value), range_text(setting));
  return static_cast<int>(value);
}

}  // namespace

std::string out_of_range_message(std::string_view value, std::string_view range) {
  std::string text = "'";
  text += value;
  text += "' is out of range (";
  text += range;
  text += ')';
  return text;
}

std::string out_of_range_text(std::string_view field, std::string_view value, std::string_view range) {
  return std::string(field) + ": " + out_of_range_message(value, range);
}

std::string range_text(const IntSetting& setting, bool with_default) {
  std::string text = std::to_string(setting.min) + " to " + std::to_string(setting.max);
  if (with_default) text += ", default " + std::to_string(setting.default_value);
  return text;
}

SettingError::SettingError(std::string field, const std::string& message)
    : std::invalid_argument(field + ": " + message), field_(std::move(field)) {}

int checked_fps(std::int64_t fps, std::string_view field) { return checked_int(fps, kFpsSetting, field); }

int checked_lookahead(std::int64_t lookahead, std::string_view field) {
  return checked_int(lookahead, kLookaheadSetting, field);
}

double checked_closure_fraction(double fraction, std::string_view field) {
  if (!(fraction > 0.0 && fraction < 1.0)) {
    out_of_range(field, shortest(fraction), "strictly between 0 and 1, default " + shortest(kDefaultClosureFraction));
  }
  return fraction;
}

int checked_mesh_subdivision(std::int64_t level, std::string_view field) {
  return checked_int(level, kMeshSubdivisionSetting, field);
}

RenderPlan resolve_render_plan(const RenderSettings& settings, const SettingNames& names) {
  RenderPlan plan;
  plan.render.fps = checked_fps(settings.fps.value_or(kFpsSetting.default_value), names.fps);
  plan.render.fixed_rate = settings.fixed_rate;
  plan.render.lookahead =
      checked_lookahead(settings.lookahead.value_or(kLookaheadSetting.default_value), names.lookahead);
  plan.segments.closure_fraction =
      checked_closure_fraction(settings.closure_fraction.value_or(kDefaultClosureFraction), names.closure_fraction);
  plan.mesh_subdivision = checked_mesh_subdivision(
      settings.mesh_subdivision.value_or(kMeshSubdivisionSetting.default_value), names.mesh_subdivision);
  return plan;
}

}  // namespace lipsync
