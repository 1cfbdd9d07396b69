// The names of the formats, each stated once. Every format family (input formats, track
// formats, viseme formats) has one table of NamedFormat in its header: the value, the name a
// user types (`--format arkit-csv`, `--input-format textgrid`) and, where the name alone does not
// say what it is, a note for help texts. Parsing a name, printing one and every list of choices
// in help and errors come from that table, so a new format is added in one place.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <string_view>

namespace lipsync {

template <class Format>
struct NamedFormat {
  Format format;
  std::string_view name;       ///< as typed on the command line
  std::string_view note = {};  ///< what it is, for help texts; empty when the name says it
};

/// The name of `format` in `table`, or "?" for a value the table lacks.
template <class Format, std::size_t N>
constexpr std::string_view name_of(const std::array<NamedFormat<Format>, N>& table, Format format) {
  for (const auto& entry : table) {
    if (entry.format == format) return entry.name;
  }
  return "?";
}

/// The format named `name` (exactly) in `table`, if any.
template <class Format, std::size_t N>
constexpr std::optional<Format> format_named(const std::array<NamedFormat<Format>, N>& table, std::string_view name) {
  for (const auto& entry : table) {
    if (entry.name == name) return entry.format;
  }
  return std::nullopt;
}

}  // namespace lipsync
