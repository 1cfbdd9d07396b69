// The command-line parser of lipsyncd and lipsync, on CLI11.
//
// A program states its options once, as a table of OptionSpec (long name,
// short name, value name, help, default); groups that several commands take
// (the connection options of the network commands) are tables of their own,
// joined at compile time. parse_arguments hands the table to CLI11 and gives
// back the values as the user wrote them, every occurrence in order, and the
// positional words; the program converts and checks the values itself, so that
// its messages name the option and the text.
//
// Accepted forms: `--name VALUE`, `--name=VALUE`, `-o VALUE`, `-oVALUE`,
// `--flag`, `-h`/`--help`; `--` ends the options; a lone `-` (stdin) and a
// negative number are positional words. A value that looks like an option
// (`--server --tls`) counts as a missing value.
//
// A bad command line throws ArgumentError, which says what was wrong and with
// which word; each program words it its own way (lipsync: "unknown option
// '--x' for 'lipsync render'", lipsyncd: "--x: unknown flag").
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace lipsync::options {

struct OptionSpec {
  std::string_view name;          ///< long name without dashes: "fps"
  char short_name = 0;            ///< 'o' for -o; 0 for none
  std::string_view value_name;    ///< "N", "FILE"; empty for a flag
  std::string_view help;          ///< what it does, with its range
  std::string_view default_text;  ///< shown as "(default: ...)"; empty for none
};

/// The tables one after the other: a command's options from shared groups and its own.
template <std::size_t... Sizes>
constexpr std::array<OptionSpec, (Sizes + ...)> join(const std::array<OptionSpec, Sizes>&... tables) {
  std::array<OptionSpec, (Sizes + ...)> joined{};
  auto out = joined.begin();
  ((out = std::copy(tables.begin(), tables.end(), out)), ...);
  return joined;
}

/// A command line that matched its table.
class ParsedArguments {
 public:
  bool help() const { return help_; }
  bool flag(std::string_view name) const { return values_.count(std::string(name)) > 0; }
  /// The last value given for `name`; nullopt when the option was not given.
  std::optional<std::string> value(std::string_view name) const;
  /// Every value given for `name`, in command-line order.
  std::vector<std::string> values(std::string_view name) const;
  const std::vector<std::string>& positional() const { return positional_; }

 private:
  friend ParsedArguments parse_arguments(std::vector<std::string> args, std::span<const OptionSpec> options);
  bool help_ = false;
  std::map<std::string, std::vector<std::string>, std::less<>> values_;  // a flag has one "" per use
  std::vector<std::string> positional_;
};

/// What was wrong with a command line; what() is a plain default wording.
class ArgumentError : public std::runtime_error {
 public:
  enum class Kind {
    unknown_option,    ///< `argument` names no option of the table
    missing_value,     ///< `option` needs a value (`value_name`) and got none
    unexpected_value,  ///< `option` is a flag and was given `value`
  };
  ArgumentError(Kind kind, std::string argument, std::string option, std::string value_name, std::string value);

  Kind kind() const { return kind_; }
  const std::string& argument() const { return argument_; }  ///< the word as written: "--fps=3", "-x"
  const std::string& option() const { return option_; }      ///< "--fps" (or "-o" as written); "" if unknown
  const std::string& value_name() const { return value_name_; }
  const std::string& value() const { return value_; }

 private:
  Kind kind_;
  std::string argument_;
  std::string option_;
  std::string value_name_;
  std::string value_;
};

/// Parses `args` (the words after the program or command name) against `options`.
/// Throws ArgumentError.
ParsedArguments parse_arguments(std::vector<std::string> args, std::span<const OptionSpec> options);

/// The whole number that all of `text` spells, strictly (no spaces, no '+', no fraction).
struct WholeNumber {
  enum class Status { ok, not_a_number, beyond_64_bits };
  Status status = Status::not_a_number;
  std::int64_t value = 0;
};
WholeNumber read_whole_number(std::string_view text);

}  // namespace lipsync::options
