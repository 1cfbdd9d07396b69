#include "arguments.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

#include "cli_error.hpp"

namespace lipsync::cli {
namespace {

std::string in_quotes(std::string_view text) { return "'" + std::string(text) + "'"; }

const OptionSpec* find_long(std::span<const OptionSpec> options, std::string_view name) {
  const auto it = std::find_if(options.begin(), options.end(),
                               [&](const OptionSpec& spec) { return spec.name == name; });
  return it == options.end() ? nullptr : &*it;
}

const OptionSpec* find_short(std::span<const OptionSpec> options, char name) {
  const auto it = std::find_if(options.begin(), options.end(),
                               [&](const OptionSpec& spec) { return spec.short_name == name; });
  return it == options.end() ? nullptr : &*it;
}

/// "--anything", or a short option of this command ("-o", "-h"); "-3" and "-" are values.
bool looks_like_option(std::string_view arg, std::span<const OptionSpec> options) {
  if (arg.starts_with("--")) return true;
  return arg.size() == 2 && arg[0] == '-' && (arg[1] == 'h' || find_short(options, arg[1]) != nullptr);
}

}  // namespace

Arguments Arguments::parse(std::span<const std::string_view> args, std::span<const OptionSpec> options,
                           std::string_view command) {
  Arguments parsed;
  const std::string see_help = " (see 'lipsync " + std::string(command) + " --help')";
  bool options_ended = false;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string_view arg = args[i];
    if (options_ended || arg == "-" || !arg.starts_with('-')) {
      parsed.positional_.emplace_back(arg);
      continue;
    }
    if (arg == "--") {
      options_ended = true;
      continue;
    }
    if (arg == "-h" || arg == "--help") {
      parsed.help_ = true;
      continue;
    }

    const OptionSpec* spec = nullptr;
    std::string shown;  // the option as the user wrote it, for messages
    std::optional<std::string_view> inline_value;
    if (arg.starts_with("--")) {
      std::string_view name = arg.substr(2);
      if (const std::size_t equals = name.find('='); equals != std::string_view::npos) {
        inline_value = name.substr(equals + 1);
        name = name.substr(0, equals);
      }
      spec = find_long(options, name);
      shown = "--" + std::string(name);
    } else if (arg.size() == 2) {
      spec = find_short(options, arg[1]);
      shown = std::string(arg);
    }
    if (spec == nullptr) {
      throw UsageError("unknown option " + in_quotes(arg) + " for 'lipsync " + std::string(command) + "'" +
                       see_help);
    }

    std::string value;
    if (spec->value_name.empty()) {
      if (inline_value) throw UsageError("option " + shown + " takes no value, got " + in_quotes(*inline_value));
    } else if (inline_value) {
      value = std::string(*inline_value);
    } else if (i + 1 < args.size() && !looks_like_option(args[i + 1], options)) {
      value = std::string(args[++i]);
    } else {
      throw UsageError("option " + shown + " needs a value (" + std::string(spec->value_name) + ")" +
                       see_help);
    }
    parsed.values_[std::string(spec->name)] = std::move(value);
  }
  return parsed;
}

std::optional<std::string> Arguments::value(std::string_view name) const {
  const auto it = values_.find(std::string(name));
  if (it == values_.end()) return std::nullopt;
  return it->second;
}

namespace {

/// The whole number `text` spells (nullopt if it does not fit in 64 bits);
/// UsageError naming `--option` if it spells none.
std::optional<std::int64_t> whole_number(std::string_view option, std::string_view text) {
  std::int64_t number = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), number);
  if (text.empty() || error == std::errc::invalid_argument || end != text.data() + text.size()) {
    throw UsageError("--" + std::string(option) + ": " + in_quotes(text) + " is not a whole number");
  }
  if (error == std::errc::result_out_of_range) return std::nullopt;
  return number;
}

}  // namespace

int parse_int_option(std::string_view option, std::string_view text, int min, int max) {
  const std::optional<std::int64_t> number = whole_number(option, text);
  if (!number || *number < min || *number > max) {
    throw UsageError("--" + std::string(option) + ": " + in_quotes(text) + " is out of range (" +
                     std::to_string(min) + " to " + std::to_string(max) + ")");
  }
  return static_cast<int>(*number);
}

std::int64_t parse_whole_option(std::string_view option, std::string_view text) {
  const std::optional<std::int64_t> number = whole_number(option, text);
  if (!number) throw UsageError("--" + std::string(option) + ": " + in_quotes(text) + " is out of range");
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

std::string format_help(std::string_view usage, std::string_view description,
                        std::span<const OptionSpec> options) {
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
