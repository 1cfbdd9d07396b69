// parse_arguments: the table becomes a CLI::App (each option keeps every value
// it is given; extras are allowed so that unknown words come back to us in
// order), CLI11 takes the words apart, and its few failures become an
// ArgumentError that names the word. Two things CLI11 2.1 does differently
// from what a user of these programs expects are settled around it: an empty
// `--name=` would take the next word as its value (it is split into `--name`
// and an empty word first), and a missing value followed by another option
// (`--server --tls`) would take that option as the value (checked after).
#include "lipsync/options/command_line.hpp"

#include <CLI/CLI.hpp>
#include <charconv>

namespace lipsync::options {
namespace {

const OptionSpec* find_long(std::span<const OptionSpec> options, std::string_view name) {
  const auto it =
      std::find_if(options.begin(), options.end(), [&](const OptionSpec& spec) { return spec.name == name; });
  return it == options.end() ? nullptr : &*it;
}

const OptionSpec* find_short(std::span<const OptionSpec> options, char name) {
  const auto it =
      std::find_if(options.begin(), options.end(), [&](const OptionSpec& spec) { return spec.short_name == name; });
  return it == options.end() ? nullptr : &*it;
}

/// "--anything", or a short option of this table ("-o", "-h"); "-3" and "-" are values.
bool looks_like_option(std::string_view word, std::span<const OptionSpec> options) {
  if (word.starts_with("--")) return true;
  return word.size() == 2 && word[0] == '-' && (word[1] == 'h' || find_short(options, word[1]) != nullptr);
}

/// `--name=` becomes `--name` and an empty word, up to a `--`.
void split_empty_inline_values(std::vector<std::string>& args) {
  for (std::size_t i = 0; i < args.size() && args[i] != "--"; ++i) {
    if (args[i].size() > 3 && args[i].starts_with("--") && args[i].find('=') == args[i].size() - 1) {
      args[i].pop_back();
      args.insert(args.begin() + static_cast<std::ptrdiff_t>(i) + 1, std::string());
      ++i;
    }
  }
}

/// CLI11 stopped at a flag given a value or at an option left without one: which word it was.
ArgumentError mismatch_in(const std::vector<std::string>& args, std::span<const OptionSpec> options) {
  for (const std::string& word : args) {
    if (word == "--") break;
    const std::size_t equals = word.find('=');
    if (!word.starts_with("--") || equals == std::string::npos) continue;
    const OptionSpec* spec = find_long(options, std::string_view(word).substr(2, equals - 2));
    if (spec != nullptr && spec->value_name.empty()) {
      return {ArgumentError::Kind::unexpected_value, word, word.substr(0, equals), "", word.substr(equals + 1)};
    }
  }
  // A missing value can only be at the end: the option is the last word.
  const std::string& last = args.back();
  const OptionSpec* spec = last.starts_with("--") ? find_long(options, std::string_view(last).substr(2))
                           : last.size() == 2     ? find_short(options, last[1])
                                                  : nullptr;
  return {ArgumentError::Kind::missing_value, last, last, spec != nullptr ? std::string(spec->value_name) : "", ""};
}

std::string default_wording(ArgumentError::Kind kind, const std::string& argument, const std::string& option) {
  switch (kind) {
    case ArgumentError::Kind::unknown_option:
      return "unknown option '" + argument + "'";
    case ArgumentError::Kind::missing_value:
      return "option " + option + " needs a value";
    case ArgumentError::Kind::unexpected_value:
      return "option " + option + " takes no value";
  }
  return argument;
}

}  // namespace

ArgumentError::ArgumentError(Kind kind, std::string argument, std::string option, std::string value_name,
                             std::string value)
    : std::runtime_error(default_wording(kind, argument, option)),
      kind_(kind),
      argument_(std::move(argument)),
      option_(std::move(option)),
      value_name_(std::move(value_name)),
      value_(std::move(value)) {}

std::optional<std::string> ParsedArguments::value(std::string_view name) const {
  const auto it = values_.find(name);
  if (it == values_.end() || it->second.empty()) return std::nullopt;
  return it->second.back();
}

std::vector<std::string> ParsedArguments::values(std::string_view name) const {
  const auto it = values_.find(name);
  return it == values_.end() ? std::vector<std::string>{} : it->second;
}

ParsedArguments parse_arguments(std::vector<std::string> args, std::span<const OptionSpec> options) {
  split_empty_inline_values(args);

  CLI::App app;
  app.set_help_flag();  // help is a flag like any other: the program prints its own
  app.allow_extras();   // unknown words come back in order, for a message naming the first
  CLI::Option* help = app.add_flag("-h,--help");
  std::vector<CLI::Option*> declared;
  for (const OptionSpec& spec : options) {
    std::string names = "--" + std::string(spec.name);
    if (spec.short_name != 0) names = std::string("-") + spec.short_name + "," + names;
    CLI::Option* option = spec.value_name.empty() ? app.add_flag(names)->disable_flag_override()
                                                  : app.add_option(names)->type_name(std::string(spec.value_name));
    declared.push_back(option->multi_option_policy(CLI::MultiOptionPolicy::TakeAll));
  }
  ParsedArguments parsed;
  app.add_option("words", parsed.positional_);

  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them last first
  try {
    app.parse(reversed);
  } catch (const CLI::ArgumentMismatch&) {
    throw mismatch_in(args, options);
  }

  std::vector<std::string> unknown = app.remaining();
  if (const auto marker = std::find(unknown.begin(), unknown.end(), "--"); marker != unknown.end()) {
    unknown.erase(marker);  // the `--` that ended the options
  }
  if (!unknown.empty()) throw ArgumentError(ArgumentError::Kind::unknown_option, unknown.front(), "", "", "");

  parsed.help_ = help->count() > 0;
  for (std::size_t i = 0; i < options.size(); ++i) {
    const OptionSpec& spec = options[i];
    if (declared[i]->count() == 0) continue;
    std::vector<std::string>& values = parsed.values_[std::string(spec.name)];
    if (spec.value_name.empty()) {
      values.assign(declared[i]->count(), std::string());
      continue;
    }
    values = declared[i]->results();
    for (const std::string& value : values) {
      if (looks_like_option(value, options)) {
        const std::string option = "--" + std::string(spec.name);
        throw ArgumentError(ArgumentError::Kind::missing_value, option, option, std::string(spec.value_name), "");
      }
    }
  }
  return parsed;
}

WholeNumber read_whole_number(std::string_view text) {
  WholeNumber number;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), number.value);
  if (text.empty() || error == std::errc::invalid_argument || end != text.data() + text.size()) {
    number.status = WholeNumber::Status::not_a_number;
  } else if (error == std::errc::result_out_of_range) {
    number.status = WholeNumber::Status::beyond_64_bits;
  } else {
    number.status = WholeNumber::Status::ok;
  }
  return number;
}

}  // namespace lipsync::options
