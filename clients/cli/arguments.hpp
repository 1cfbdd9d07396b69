// The command line of a `lipsync` command: its options are a table of
// OptionSpec (lipsync::options, CLI11 underneath), shared groups joined in
// with options::join; the same table prints the command's --help, so the two
// cannot drift apart. Mistakes become a UsageError naming the command:
//   unknown option '--x' for 'lipsync render' (see 'lipsync render --help')
//   option --fps needs a value (N) (see 'lipsync render --help')
// Numbers are parsed strictly: the whole text must be the number.
#pragma once

#include <cstdint>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/options/command_line.hpp"
#include "lipsync/setting_ranges.hpp"

namespace lipsync::cli {

using options::join;
using options::OptionSpec;

class Arguments : public options::ParsedArguments {
 public:
  /// Parses `args` (the words after the command name). Throws UsageError
  /// naming the option for an unknown option or a missing value. `command`
  /// (e.g. "render") names the command in messages.
  static Arguments parse(std::span<const std::string_view> args, std::span<const OptionSpec> options,
                         std::string_view command);

 private:
  explicit Arguments(options::ParsedArguments parsed) : options::ParsedArguments(std::move(parsed)) {}
};

/// Whole number in [min, max]; UsageError naming `--option` and the text otherwise.
int parse_int_option(std::string_view option, std::string_view text, int min, int max);

/// Whole number that fits in 64 bits (its range is checked by the caller);
/// UsageError naming `--option` and the text otherwise.
std::int64_t parse_whole_option(std::string_view option, std::string_view text);

/// The option's whole number within `setting`'s range, or its default when it is not given;
/// UsageError naming `--option`, the text and the range otherwise.
int parse_setting_option(const Arguments& arguments, std::string_view option, IntSetting setting);

/// Finite decimal number; UsageError naming `--option` and the text otherwise.
double parse_double_option(std::string_view option, std::string_view text);

/// `text` broken at spaces into lines of at most `line_width` columns, for a
/// text that starts at column `indent`; continuation lines are indented to it.
std::string wrap_text(std::string_view text, std::size_t indent, std::size_t line_width = 80);

/// The --help text: usage line, description, then one line per option.
std::string format_help(std::string_view usage, std::string_view description, std::span<const OptionSpec> options);

/// If `arguments` asked for --help, writes the command's help (format_help) to
/// `out` and returns true: the command then exits 0 without doing anything else.
bool print_help_if_asked(const Arguments& arguments, std::string_view usage, std::string_view description,
                         std::span<const OptionSpec> options, std::ostream& out);

}  // namespace lipsync::cli
