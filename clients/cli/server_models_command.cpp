// `lipsync server-models [NAME]`: the models a running lipsyncd animates with
// (ListModels), or one of them (GetModel), as text for a person or --json for
// scripts. Unlike `lipsync model dump`, which prints the local built-in model
// file, this asks a server, which may hold models loaded with --model NAME=FILE.
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "network.hpp"

namespace lipsync::cli {
namespace {

/// --timeout: ListModels and GetModel answer at once.
constexpr IntSetting kModelsTimeoutSetting = {1, 3600, 5};

constexpr auto kOptions =
    join(kConnectionOptions,
         std::to_array<OptionSpec>({
             {"json", 0, "", "print JSON: {\"models\": [MODEL...]} without NAME, MODEL with it", ""},
             kTimeoutOption<"give up when the server has not answered after S seconds", kModelsTimeoutSetting>,
         }));

constexpr std::string_view kUsage = "lipsync server-models [NAME] [options]";
constexpr std::string_view kDescription =
    "Asks lipsyncd which articulation models it animates with (ListModels), or describes\n"
    "the model NAME (GetModel): channels with kind, range, rest value and meaning, the\n"
    "number of ARKit blendshapes, the phoneme inventory and the phone sets it accepts.\n"
    "Use a NAME with 'lipsync stream --server-model NAME'. ('lipsync model dump' prints\n"
    "the local built-in model file instead.)";

std::string number(double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", value);
  return text;
}

std::string joined(const google::protobuf::RepeatedPtrField<std::string>& items) {
  std::string text;
  for (const std::string& item : items) text += (text.empty() ? "" : " ") + item;
  return text.empty() ? "(none)" : text;
}

void print_model(const client::v1::ModelInfo& info, std::ostream& out) {
  out << "model " << info.name() << (info.is_default() ? " (default)" : "") << '\n';
  std::size_t name_width = 4;
  std::size_t kind_width = 4;
  for (const auto& channel : info.channels()) {
    name_width = std::max(name_width, channel.name().size());
    kind_width = std::max(kind_width, channel.kind().size());
  }
  out << "  channels: " << info.channels_size() << '\n';
  const auto row = [&](const std::string& name, const std::string& kind, const std::string& min, const std::string& max,
                       const std::string& rest, const std::string& description) {
    char cells[64];
    std::snprintf(cells, sizeof cells, "  %8s %8s %8s  ", min.c_str(), max.c_str(), rest.c_str());
    const std::string left = "    " + name + std::string(name_width - name.size() + 2, ' ') + kind +
                             std::string(kind_width - kind.size(), ' ') + cells;
    out << left << wrap_text(description, left.size()) << '\n';
  };
  row("name", "kind", "min", "max", "rest", "description");
  for (const auto& channel : info.channels()) {
    row(channel.name(), channel.kind(), number(channel.min()), number(channel.max()), number(channel.rest()),
        channel.description());
  }
  out << "  ARKit blendshapes: " << info.arkit_names_size() << '\n';
  const std::string phonemes_label = "  phonemes (" + std::to_string(info.phonemes_size()) + "): ";
  out << phonemes_label << wrap_text(joined(info.phonemes()), phonemes_label.size()) << '\n';
  out << "  phone sets: " << joined(info.phone_sets()) << '\n';
}

nlohmann::ordered_json to_json(const client::v1::ModelInfo& info) {
  nlohmann::ordered_json channels = nlohmann::ordered_json::array();
  for (const auto& channel : info.channels()) {
    channels.push_back({{"name", channel.name()},
                        {"kind", channel.kind()},
                        {"min", channel.min()},
                        {"max", channel.max()},
                        {"rest", channel.rest()},
                        {"description", channel.description()}});
  }
  return {
      {"name", info.name()},
      {"default", info.is_default()},
      {"channels", channels},
      {"arkit_names", std::vector<std::string>(info.arkit_names().begin(), info.arkit_names().end())},
      {"phonemes", std::vector<std::string>(info.phonemes().begin(), info.phonemes().end())},
      {"phone_sets", std::vector<std::string>(info.phone_sets().begin(), info.phone_sets().end())},
  };
}

}  // namespace

int run_server_models(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "server-models");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (arguments.positional().size() > 1) {
    throw UsageError("server-models takes at most one model NAME, got '" + arguments.positional()[1] +
                     "' too (see 'lipsync server-models --help')");
  }
  if (!arguments.positional().empty() && arguments.positional().front().empty()) {
    throw UsageError("server-models: the model NAME must not be empty (leave it out to list every model)");
  }
  const std::string address = server_address(arguments);
  const int timeout_s = parse_setting_option(arguments, "timeout", kModelsTimeoutSetting);
  const bool json = arguments.flag("json");

  client::ClientOptions options = connection_options(arguments);
  options.connect_timeout = std::chrono::seconds(timeout_s);
  options.unary_timeout = std::chrono::seconds(timeout_s);
  const client::AnimationClient connection(address, options);
  connection.wait_connected();
  if (!arguments.positional().empty()) {
    const client::v1::ModelInfo info = connection.get_model(arguments.positional().front());
    if (json) {
      std::cout << to_json(info).dump(2) << '\n';
    } else {
      print_model(info, std::cout);
    }
    return 0;
  }
  const client::v1::ListModelsResponse list = connection.list_models();
  if (json) {
    nlohmann::ordered_json models = nlohmann::ordered_json::array();
    for (const auto& info : list.models()) models.push_back(to_json(info));
    std::cout << nlohmann::ordered_json{{"models", models}}.dump(2) << '\n';
    return 0;
  }
  for (int i = 0; i < list.models_size(); ++i) {
    if (i > 0) std::cout << '\n';
    print_model(list.models(i), std::cout);
  }
  return 0;
}

}  // namespace lipsync::cli
