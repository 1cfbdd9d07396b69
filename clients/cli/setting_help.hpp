// Help texts that quote a render setting's range and default from
// lipsync/setting_ranges.hpp, the one place they are stated.
//
// The option tables (OptionSpec) are constexpr and hold string_views, so the
// texts are built at compile time: `ranged_help<"frames per second", kFpsSetting>`
// is the characters "frames per second, 1 to 240", and
// `default_text<kFpsSetting>` is "30". Changing a range in setting_ranges.hpp
// changes `--help`, the error texts (SettingError) and the checks together.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "lipsync/setting_ranges.hpp"

namespace lipsync::cli {

/// A string of N - 1 characters (and a terminating zero) usable as a template argument.
template <std::size_t N>
struct FixedText {
  char chars[N]{};
  constexpr FixedText() = default;
  constexpr FixedText(const char (&text)[N]) { std::copy_n(text, N, chars); }  // NOLINT: implicit by design
  constexpr std::string_view view() const { return {chars, N - 1}; }
  static constexpr std::size_t kLength = N - 1;
};

namespace setting_help_detail {

constexpr std::size_t decimal_length(std::int64_t value) {
  std::size_t length = value < 0 ? 2 : 1;
  for (std::int64_t rest = value / 10; rest != 0; rest /= 10) ++length;
  return length;
}

/// Writes `value` in decimal at `out`; returns the end.
constexpr char* write_decimal(std::int64_t value, char* out) {
  const std::size_t length = decimal_length(value);
  char* end = out + length;
  if (value < 0) *out = '-';
  char* digit = end;
  do {
    const std::int64_t remainder = value % 10;
    *--digit = static_cast<char>('0' + (remainder < 0 ? -remainder : remainder));
    value /= 10;
  } while (value != 0);
  return end;
}

constexpr char* write_text(std::string_view text, char* out) { return std::copy(text.begin(), text.end(), out); }

template <FixedText Lead, IntSetting Setting, FixedText Tail>
constexpr auto make_ranged_help() {
  constexpr std::string_view kSeparator = ", ";
  constexpr std::string_view kTo = " to ";
  constexpr std::size_t kLength = Lead.kLength + kSeparator.size() + decimal_length(Setting.min) + kTo.size() +
                                  decimal_length(Setting.max) + Tail.kLength;
  FixedText<kLength + 1> help;
  char* out = write_text(Lead.view(), help.chars);
  out = write_text(kSeparator, out);
  out = write_decimal(Setting.min, out);
  out = write_text(kTo, out);
  out = write_decimal(Setting.max, out);
  write_text(Tail.view(), out);
  return help;
}

template <IntSetting Setting>
constexpr auto make_default_text() {
  FixedText<decimal_length(Setting.default_value) + 1> text;
  write_decimal(Setting.default_value, text.chars);
  return text;
}

}  // namespace setting_help_detail

/// "<Lead>, <min> to <max><Tail>": an option's help with the setting's range.
template <FixedText Lead, IntSetting Setting, FixedText Tail = "">
inline constexpr auto kRangedHelp = setting_help_detail::make_ranged_help<Lead, Setting, Tail>();

/// The setting's default in decimal, for OptionSpec::default_text.
template <IntSetting Setting>
inline constexpr auto kDefaultText = setting_help_detail::make_default_text<Setting>();

static_assert(kRangedHelp<"fps", IntSetting{1, 240, 30}>.view() == "fps, 1 to 240");
static_assert(kRangedHelp<"x", IntSetting{-12, 0, 0}, " (t)">.view() == "x, -12 to 0 (t)");
static_assert(kDefaultText<IntSetting{0, 9, -305}>.view() == "-305");

}  // namespace lipsync::cli
