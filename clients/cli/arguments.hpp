// A small command-line parser: each command declares its options as a table
// (name, value name, help with the default) and gets back the values as text;
// the same table prints the command's --help, so the two cannot drift apart.
//
// Accepted forms: `--name VALUE`, `--name=VALUE`, `-o VALUE`, `--flag`;
// `--` ends the options; a lone `-` is a positional argument (stdin).
// Numbers are parsed strictly: the whole text must be the number.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lipsync::cli {

struct OptionSpec {
  std::string_view name;          ///< long name without dashes: "fps"
  char short_name = 0;            ///< 'o' for -o; 0 for none
  std::string_view value_name;    ///< "N", "FILE"; empty for a flag
  std::string_view help;          ///< what it does, with its range
  std::string_view default_text;  ///< shown as "(default: ...)"; empty for none
};

class Arguments {
 public:
  /// Parses `args` (the words after the command name). Throws UsageError
  /// naming the option for an unknown option or a missing value. `command`
  /// (e.g. "render") names the command in messages.
  static Arguments parse(std::span<const std::string_view> args, std::span<const OptionSpec> options,
                         std::string_view command);

  bool help() const { return help_; }
  bool flag(std::string_view name) const { return values_.count(std::string(name)) > 0; }
  std::optional<std::string> value(std::string_view name) const;
  const std::vector<std::string>& positional() const { return positional_; }

 private:
  bool help_ = false;
  std::map<std::string, std::string> values_;  // flags map to ""
  std::vector<std::string> positional_;
};

/// Whole number in [min, max]; UsageError naming `--option` and the text otherwise.
int parse_int_option(std::string_view option, std::string_view text, int min, int max);

/// Whole number that fits in 64 bits (its range is checked by the caller);
/// UsageError naming `--option` and the text otherwise.
std::int64_t parse_whole_option(std::string_view option, std::string_view text);

/// Finite decimal number; UsageError naming `--option` and the text otherwise.
double parse_double_option(std::string_view option, std::string_view text);

/// `text` broken at spaces into lines of at most `line_width` columns, for a
/// text that starts at column `indent`; continuation lines are indented to it.
std::string wrap_text(std::string_view text, std::size_t indent, std::size_t line_width = 80);

/// The --help text: usage line, description, then one line per option.
std::string format_help(std::string_view usage, std::string_view description,
                        std::span<const OptionSpec> options);

/// If `arguments` asked for --help, writes the command's help (format_help) to
/// `out` and returns true: the command then exits 0 without doing anything else.
bool print_help_if_asked(const Arguments& arguments, std::string_view usage, std::string_view description,
                         std::span<const OptionSpec> options, std::ostream& out);

}  // namespace lipsync::cli
