// Help and error texts that list format names from the core's tables (kTrackFormats,
// kVisemeFormats, kMouthSwitchFormats, kInputFormats: lipsync/named_format.hpp), the one
// place they are stated.
//
// The option tables (OptionSpec) are constexpr and hold string_views, so the lists are built at
// compile time, as setting_help.hpp builds ranges: `kNameList<kTrackFormats, ListStyle::choice>`
// is the characters "json, csv or arkit-csv", and kJoinedText concatenates such pieces.
#pragma once

#include <cstddef>
#include <string_view>

#include "lipsync/formats.hpp"
#include "lipsync/moho_writer.hpp"
#include "lipsync/track_writer.hpp"
#include "lipsync/viseme_writer.hpp"
#include "setting_help.hpp"

namespace lipsync::cli {

/// How a list of names reads.
enum class ListStyle {
  choice,        ///< "a, b or c"
  commas,        ///< "a, b, c"
  choice_noted,  ///< "a, b or c (note of c)"
  commas_noted,  ///< "a, b, c (note of c)"
};

namespace format_choices_detail {

/// Writes `table`'s names in `style` at `out` (when not null); returns the number of characters.
template <class Table>
constexpr std::size_t write_name_list(const Table& table, ListStyle style, char* out) {
  std::size_t length = 0;
  const auto put = [&](std::string_view text) {
    if (out != nullptr) {
      for (const char ch : text) out[length++] = ch;
    } else {
      length += text.size();
    }
  };
  for (std::size_t index = 0; index < table.size(); ++index) {
    const bool noted = style == ListStyle::choice_noted || style == ListStyle::commas_noted;
    const bool or_before_last = style == ListStyle::choice || style == ListStyle::choice_noted;
    if (index > 0) put(or_before_last && index + 1 == table.size() ? " or " : ", ");
    put(table[index].name);
    if (noted && !table[index].note.empty()) {
      put(" (");
      put(table[index].note);
      put(")");
    }
  }
  return length;
}

template <const auto& Table, ListStyle Style>
constexpr auto make_name_list() {
  FixedText<write_name_list(Table, Style, nullptr) + 1> text;
  write_name_list(Table, Style, text.chars);
  return text;
}

template <FixedText... Parts>
constexpr auto make_joined_text() {
  FixedText<(Parts.kLength + ... + 0) + 1> text;
  char* out = text.chars;
  ((out = setting_help_detail::write_text(Parts.view(), out)), ...);
  return text;
}

}  // namespace format_choices_detail

/// The names of a format table (an array of NamedFormat) as a list in `Style`.
template <const auto& Table, ListStyle Style>
inline constexpr auto kNameList = format_choices_detail::make_name_list<Table, Style>();

/// The pieces, one after the other.
template <FixedText... Parts>
inline constexpr auto kJoinedText = format_choices_detail::make_joined_text<Parts...>();

static_assert(kNameList<kTrackFormats, ListStyle::choice>.view() == "json, csv or arkit-csv");
static_assert(kJoinedText<"a", "bc", "">.view() == "abc");

}  // namespace lipsync::cli
