// Guessing the input format: the content decides first, because extensions
// lie (".lab" is also HTK's format, ".txt" is anything); the extension decides
// only when the content does not match a known layout.
//
// One combination is refused instead of guessed: "integer integer label" lines
// in a .lab file are HTK labels (100 ns units), not TIMIT samples.
//
// Content rules, in order, on the first lines of the decoded text:
//   json      first non-blank character is '{'
//   textgrid  first line names "ooTextFile" or "Praat chronological TextGrid text file"
//   timit     every line is "integer integer label"
//   lab       a "#" line followed by "number integer label" lines, or such lines
//             alone when some time has a decimal point
//   flite     every token is "label:time", some time a number
//   pho       every line (';' comments aside) is "label number [number number]..."
#include <algorithm>
#include <array>
#include <cctype>
#include <string>
#include <vector>

#include "formats/text.hpp"
#include "lipsync/error.hpp"
#include "lipsync/formats.hpp"

namespace lipsync {
namespace {

using formats::is_decimal_number;
using formats::Line;
using formats::split_fields;
using formats::trim;

constexpr std::size_t kSampleLines = 40;

bool is_integer(std::string_view text) {
  if (text.starts_with('-') || text.starts_with('+')) text.remove_prefix(1);
  return !text.empty() && std::all_of(text.begin(), text.end(), [](char ch) { return ch >= '0' && ch <= '9'; });
}

// Up to kSampleLines non-blank lines, starting at `from`.
std::vector<std::string_view> sample(const std::vector<Line>& lines, std::size_t from = 0) {
  std::vector<std::string_view> out;
  for (std::size_t i = from; i < lines.size() && out.size() < kSampleLines; ++i) {
    if (!trim(lines[i].text).empty()) out.push_back(lines[i].text);
  }
  return out;
}

template <typename Predicate>
bool all_match(const std::vector<std::string_view>& lines, Predicate matches) {
  return !lines.empty() && std::all_of(lines.begin(), lines.end(), matches);
}

bool is_timit_line(std::string_view line) {
  const auto fields = split_fields(line);
  return fields.size() == 3 && is_integer(fields[0]) && is_integer(fields[1]);
}

bool is_lab_line(std::string_view line) {
  const auto fields = split_fields(line);
  return fields.size() == 3 && is_decimal_number(fields[0]) && is_integer(fields[1]);
}

// Every token has a label and a colon; the time may be malformed, so that the
// reader, not detection, reports it.
bool is_flite_line(std::string_view line) {
  const auto tokens = split_fields(line);
  return std::all_of(tokens.begin(), tokens.end(), [](std::string_view token) {
    const std::size_t colon = token.rfind(':');
    return colon != std::string_view::npos && colon > 0;
  });
}

bool has_flite_time(std::string_view line) {
  const auto tokens = split_fields(line);
  return std::any_of(tokens.begin(), tokens.end(), [](std::string_view token) {
    const std::size_t colon = token.rfind(':');
    return colon != std::string_view::npos && is_decimal_number(token.substr(colon + 1));
  });
}

bool is_pho_line(std::string_view line) {
  const auto fields = split_fields(line.substr(0, line.find(';')));
  if (fields.empty() || (fields.size() == 1 && fields[0] == "#")) return true;
  return fields.size() >= 2 && fields.size() % 2 == 0 &&
         std::all_of(fields.begin() + 1, fields.end(), [](std::string_view field) {
           if (field.ends_with('%')) field.remove_suffix(1);
           return is_decimal_number(field);
         });
}

std::optional<InputFormat> format_from_content(std::string_view text) {
  const std::string_view start = trim(text);
  if (start.starts_with('{')) return InputFormat::json;
  const std::string_view first_line = start.substr(0, start.find_first_of("\r\n"));
  if (first_line.find("\"ooTextFile") != std::string_view::npos ||
      first_line.find("\"Praat chronological TextGrid text file\"") != std::string_view::npos) {
    return InputFormat::textgrid;
  }
  const std::vector<Line> lines = formats::split_lines(text);
  const std::vector<std::string_view> head = sample(lines);
  if (all_match(head, is_timit_line)) return InputFormat::timit;
  const auto hash = std::find_if(lines.begin(), lines.end(), [](const Line& line) { return trim(line.text) == "#"; });
  if (hash != lines.end() && hash - lines.begin() < static_cast<std::ptrdiff_t>(kSampleLines) &&
      all_match(sample(lines, static_cast<std::size_t>(hash - lines.begin()) + 1), is_lab_line)) {
    return InputFormat::lab;
  }
  if (all_match(head, is_lab_line) && std::any_of(head.begin(), head.end(), [](std::string_view line) {
        return split_fields(line)[0].find('.') != std::string_view::npos;
      })) {
    return InputFormat::lab;
  }
  if (all_match(head, is_flite_line) && std::any_of(head.begin(), head.end(), has_flite_time)) {
    return InputFormat::flite;
  }
  const bool pho_has_phoneme = std::any_of(head.begin(), head.end(), [](std::string_view line) {
    return split_fields(line.substr(0, line.find(';'))).size() >= 2;
  });
  if (pho_has_phoneme && all_match(head, is_pho_line)) return InputFormat::pho;
  return std::nullopt;
}

std::optional<InputFormat> format_from_extension(std::string_view file_name) {
  const std::size_t slash = file_name.find_last_of("/\\");
  if (slash != std::string_view::npos) file_name.remove_prefix(slash + 1);
  const std::size_t dot = file_name.rfind('.');
  if (dot == std::string_view::npos) return std::nullopt;
  std::string extension(file_name.substr(dot + 1));
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](char ch) { return static_cast<char>(std::tolower(static_cast<unsigned char>(ch))); });
  constexpr std::array<std::pair<std::string_view, InputFormat>, 7> kExtensions{{
      {"json", InputFormat::json},
      {"textgrid", InputFormat::textgrid},
      {"phn", InputFormat::timit},
      {"lab", InputFormat::lab},
      {"pho", InputFormat::pho},
      {"psdur", InputFormat::flite},
      {"flite", InputFormat::flite},
  }};
  for (const auto& [known, format] : kExtensions) {
    if (extension == known) return format;
  }
  return std::nullopt;
}

}  // namespace

InputFormat detect_input_format(std::string_view file_name, std::string_view content) {
  std::string text;
  try {
    text = formats::decode_to_utf8(content, file_name);
  } catch (const InputError&) {
    text.clear();  // undecodable: only the extension can tell; the parser reports the bytes
  }
  const std::optional<InputFormat> by_content = format_from_content(text);
  const std::optional<InputFormat> by_extension = format_from_extension(file_name);
  if (by_content == InputFormat::timit && by_extension == InputFormat::lab) {
    // HTK writes .lab files as "start end label" in units of 100 ns: read as TIMIT
    // samples they would give wrong times without a word of warning.
    throw InputError(std::string(file_name), 0,
                     "this .lab file has \"start end label\" lines with whole numbers, as HTK "
                     "writes (100 ns units), which lipsyncd does not read; if it is a TIMIT .PHN "
                     "file, name the format timit explicitly");
  }
  if (by_content) return *by_content;
  if (by_extension) return *by_extension;
  throw InputError(std::string(file_name), 0,
                   "cannot tell the input format from the content or the file name; name it "
                   "explicitly: json, textgrid, timit, lab, pho or flite");
}

}  // namespace lipsync
