// `lipsync model dump` and `lipsync phone-sets`: what the renderer works with,
// printed so that a user can start a model of their own from the built-in one
// and see which label vocabularies are understood.
#include <algorithm>
#include <iostream>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "pipeline.hpp"

namespace lipsync::cli {
namespace {

constexpr OptionSpec kDumpOptions[] = {
    {"model", 0, "FILE", "print FILE after validating it, instead of the built-in model", "the built-in model"},
};

constexpr std::string_view kModelUsage = "lipsync model dump [--model FILE]";
constexpr std::string_view kModelDescription =
    "Prints the articulation model JSON (channels, phoneme targets and dominance\n"
    "parameters, ARKit retargeting). Save it, edit it, and pass it back with --model.";

constexpr std::string_view kPhoneSetsUsage = "lipsync phone-sets";
constexpr std::string_view kPhoneSetsDescription =
    "Lists the built-in phone sets (label vocabularies), in the order --phone-set auto\n"
    "tries them.";

}  // namespace

int run_model(std::span<const std::string_view> args) {
  if (args.empty()) throw UsageError("model needs a subcommand: dump (see 'lipsync model --help')");
  if (args.front() == "-h" || args.front() == "--help") {
    std::cout << format_help(kModelUsage, kModelDescription, kDumpOptions);
    return 0;
  }
  if (args.front() != "dump") {
    throw UsageError("unknown 'lipsync model' subcommand '" + std::string(args.front()) + "' (available: dump)");
  }
  const Arguments arguments = Arguments::parse(args.subspan(1), kDumpOptions, "model dump");
  if (print_help_if_asked(arguments, kModelUsage, kModelDescription, kDumpOptions, std::cout)) return 0;
  if (!arguments.positional().empty()) {
    throw UsageError("model dump takes no arguments, got '" + arguments.positional().front() + "'");
  }
  const ModelSource source(arguments.value("model"));
  const std::string& text = source.json_text();
  std::cout << text;
  if (!text.empty() && text.back() != '\n') std::cout << '\n';
  return 0;
}

int run_phone_sets(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, {}, "phone-sets");
  if (print_help_if_asked(arguments, kPhoneSetsUsage, kPhoneSetsDescription, {}, std::cout)) return 0;
  if (!arguments.positional().empty()) {
    throw UsageError("phone-sets takes no arguments, got '" + arguments.positional().front() + "'");
  }
  const std::vector<PhoneSet> sets = PhoneSet::builtin_all(ArticulationModel::builtin());
  std::size_t width = 4;
  for (const PhoneSet& set : sets) width = std::max(width, set.name().size());
  const auto print = [&](const std::string& name, std::string_view description) {
    std::cout << name << std::string(width - name.size() + 2, ' ') << wrap_text(description, width + 2) << '\n';
  };
  for (const PhoneSet& set : sets) print(set.name(), set.description());
  print("auto", "detect: the first set above that knows every label of the input");
  return 0;
}

}  // namespace lipsync::cli
