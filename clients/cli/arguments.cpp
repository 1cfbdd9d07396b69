#include "arguments.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <vector>

#include "cli_error.hpp"

namespace lipsync::cli {
namespace {

std::string in_quotes(std::string_view text) { return "'" + std::string(text) + "'"; }

/// UsageError naming `--option` when `text` is no whole number; the number, or nullopt beyond 64 bits.
std::optional<std::int64_t> whole_number(std::string_view option, std::string_view text) {
  const options::WholeNumber number = options::read_whole_number(text);
  if (number.status == options::WholeNumber::Status::not_a_number) {
    throw UsageError("--" + std::string(option) + ": " + in_quotes(text) + " is not a whole number");
  }
  if (number.status == options::WholeNumber::Status::beyond_64_bits) return std::nullopt;
  return number.value;
}

}  // namespace

Arguments Arguments::parse(std::span<const std::string_view> args, std::span<const OptionSpec> options,
                           std::string_view command) {
  const std::string see_help = " (see 'lipsync " + std::string(command) + " --help')";
  try {
    return Arguments(options::parse_arguments(std::vector<std::string>(args.begin(), args.end()), options));
  } catch (const options::ArgumentError& error) {
    switch (error.kind()) {
      case options::ArgumentError::Kind::unknown_option:
        throw UsageError("unknown option " + in_quotes(error.argument()) + " for 'lipsync " + std::string(command) +
                         "'" + see_help);
      case options::ArgumentError::Kind::missing_value:
        throw UsageError("option " + error.option() + " needs a value (" + error.value_name() + ")" + see_help);
      case options::ArgumentError::Kind::unexpected_value:
        throw UsageError("option " + error.option() + " takes no value, got " + in_quotes(error.value()));
    }
    throw;
  }
}

int parse_int_option(std::string_view option, std::string_view text, int min, int max) {
  const std::optional<std::int64_t> number = whole_number(option, text);
  if (!number || *number < min || *number > max) {
    throw UsageError(out_of_range_text("--" + std::string(option), text, range_text(IntSetting{min, max, 0}, false)));
  }
  return static_cast<int>(*number);
}

int parse_setting_option(const Arguments& arguments, std::string_view option, IntSetting setting) {
  const std::optional<std::string> text = arguments.value(option);
  if (!text) return static_cast<int>(setting.default_value);
  return parse_int_option(option, *text, static_cast<int>(setting.min), static_cast<int>(setting.max));
}

std::int64_t parse_whole_option(std::string_view option, std::string_view text) {
  const std::optional<std::int64_t> number = whole_number(option, text);
  if (!number) throw UsageError(out_of_range_text("--" + std::string(option), text, "a whole number within 64 bits"));
  return *number;
}

double parse_double_option(std::string_view option, std::string_view text) {
  double number = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), number);
  if (text.empty() || error != std::errc() || end != text.data() + text.size() || !std::isfinite(number)) {
    throw UsageError("--" + std::string(option) + ": " + in_quotes(text) + " is not a finite number");
  }
  return number;
}

std::string wrap_text(std::string_view text, std::size_t indent, std::size_t line_width) {
  const std::size_t width = indent + 40 < line_width ? line_width - indent : 40;
  std::string wrapped;
  std::size_t column = 0;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find(' ', start);
    if (end == std::string_view::npos) end = text.size();
    const std::size_t word = end - start;
    if (column > 0 && column + 1 + word > width) {
      wrapped += "\n" + std::string(indent, ' ');
      column = 0;
    } else if (column > 0) {
      wrapped += ' ';
      ++column;
    }
    wrapped.append(text.substr(start, word));
    column += word;
    start = end + 1;
  }
  return wrapped;
}

std::string format_help(std::string_view usage, std::string_view description, std::span<const OptionSpec> options) {
  std::string help = "Usage: " + std::string(usage) + "\n\n" + std::string(description) + "\n\nOptions:\n";
  const auto left_column = [](const OptionSpec& spec) {
    std::string text = spec.short_name != 0 ? std::string("-") + spec.short_name + ", " : "    ";
    text += "--" + std::string(spec.name);
    if (!spec.value_name.empty()) text += " " + std::string(spec.value_name);
    return text;
  };
  std::size_t width = std::string("-h, --help").size();
  for (const OptionSpec& spec : options) width = std::max(width, left_column(spec).size());
  const auto add_line = [&](const std::string& left, const std::string& text) {
    help += "  " + left + std::string(width - left.size() + 2, ' ') + wrap_text(text, width + 4) + "\n";
  };
  for (const OptionSpec& spec : options) {
    std::string text(spec.help);
    if (!spec.default_text.empty()) text += " (default: " + std::string(spec.default_text) + ")";
    add_line(left_column(spec), text);
  }
  add_line("-h, --help", "show this help and exit");
  return help;
}

bool print_help_if_asked(const Arguments& arguments, std::string_view usage, std::string_view description,
                         std::span<const OptionSpec> options, std::ostream& out) {
  if (!arguments.help()) return false;
  out << format_help(usage, description, options);
  return true;
}

}  // namespace lipsync::cli
