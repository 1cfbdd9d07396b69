// Input format names (kInputFormats, formats.hpp) and the entry point that decodes the text
// and hands it to the reader of the chosen format.
#include <algorithm>
#include <array>
#include <cctype>
#include <string>
#include <utility>

#include "formats/readers.hpp"
#include "formats/text.hpp"
#include "lipsync/error.hpp"
#include "lipsync/formats.hpp"

namespace lipsync {

std::string_view to_string(InputFormat format) { return name_of(kInputFormats, format); }

std::optional<InputFormat> input_format_from_string(std::string_view name) {
  std::string lower(name);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](char ch) { return static_cast<char>(std::tolower(static_cast<unsigned char>(ch))); });
  return format_named(kInputFormats, lower);
}

LabeledUtterance parse_utterance(std::string_view content, InputFormat format, std::string_view source,
                                 const ParseOptions& options) {
  const std::string name(source);
  const std::string text = formats::decode_to_utf8(content, source);
  switch (format) {
    case InputFormat::json:
      return formats::read_json_utterance(text, name);
    case InputFormat::textgrid:
      return formats::read_textgrid(text, name, options.tier);
    case InputFormat::timit:
      return formats::read_timit(text, name, options.timit_sample_rate_hz);
    case InputFormat::lab:
      return formats::read_lab(text, name);
    case InputFormat::pho:
      return formats::read_pho(text, name);
    case InputFormat::flite:
      return formats::read_flite(text, name);
  }
  throw InputError(name, 0, "unknown input format");
}

}  // namespace lipsync
