// Readers for the files that aligners and TTS front-ends write, turning text
// into a LabeledUtterance. They work on strings (the caller reads the file),
// report every problem as an InputError with the file name and 1-based line,
// and never guess silently: a malformed line is an error, not a skipped line.
//
// Formats (docs/input-formats.md):
//   json         lipsync utterance JSON {"phone_set", "phonemes": [{label,start,end}]}
//   textgrid     Praat TextGrid, long / short / chronological, UTF-8 or UTF-16 with BOM
//   timit        TIMIT .PHN: "start_sample end_sample label", sample rate option
//   lab          Festival / CMU ARCTIC .lab: "end_time 100 label" after a "#" line
//   pho          MBROLA .pho: "label duration_ms [pos pitch]...", ';' comments
//   flite        flite -psdur output: "label:end_time label:end_time ..."
#pragma once

#include <optional>
#include <string>
#include <string_view>

#include "lipsync/named_format.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync {

enum class InputFormat { json, textgrid, timit, lab, pho, flite };

/// The input formats by name, in the order help lists them.
inline constexpr std::array<NamedFormat<InputFormat>, 6> kInputFormats{{
    {InputFormat::json, "json"},
    {InputFormat::textgrid, "textgrid"},
    {InputFormat::timit, "timit"},
    {InputFormat::lab, "lab"},
    {InputFormat::pho, "pho"},
    {InputFormat::flite, "flite"},
}};

std::string_view to_string(InputFormat format);
std::optional<InputFormat> input_format_from_string(std::string_view name);

struct ParseOptions {
  std::string tier = "phones";       ///< TextGrid tier name
  int timit_sample_rate_hz = 16000;  ///< TIMIT .PHN sample rate
};

/// Guesses the format from the content first, then the file extension
/// (.json .TextGrid .PHN .lab .pho .psdur/.flite). Throws InputError if neither tells.
InputFormat detect_input_format(std::string_view file_name, std::string_view content);

/// Parses `content` (raw bytes of the file) in `format`. `source` names the file
/// in messages. Times are rounded to the nearest microsecond.
LabeledUtterance parse_utterance(std::string_view content, InputFormat format, std::string_view source,
                                 const ParseOptions& options = {});

}  // namespace lipsync
