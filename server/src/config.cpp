// Command line, environment and JSON configuration for lipsyncd.
//
// One table lists every option: its flag, a value hint, the help line, how to
// apply a value and how to show the default. The flag parser (lipsync::options,
// CLI11, the one lipsync uses too), the environment reader, the JSON file reader
// and `--help` all walk that table, so they cannot disagree. The environment and
// the file are read here, not by CLI11: its variables are read with getenv and
// its files are TOML/INI, while ours are JSON, come from an injectable
// Environment, sit under the variables and name the variable or file key in errors.
#include "lipsync/server/config.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string_view>

#include "lipsync/options/command_line.hpp"
#include "lipsync/setting_ranges.hpp"

namespace lipsync::server {
namespace {

struct Setting {
  std::string name;  // flag or JSON key, e.g. "--max-streams"
  std::string value;
};

std::int64_t parse_integer(const Setting& setting, std::int64_t min, std::int64_t max) {
  const options::WholeNumber number = options::read_whole_number(setting.value);
  if (number.status != options::WholeNumber::Status::ok) {
    throw ConfigError(setting.name + ": expected an integer, got '" + setting.value + "'");
  }
  const std::int64_t value = number.value;
  if (value < min || value > max) {
    throw ConfigError(out_of_range_text(setting.name, setting.value, range_text(IntSetting{min, max, 0}, false)));
  }
  return value;
}

std::size_t parse_count(const Setting& setting, std::size_t min) {
  return static_cast<std::size_t>(
      parse_integer(setting, static_cast<std::int64_t>(min), std::numeric_limits<std::int32_t>::max()));
}

/// HOST:PORT with a port 0..65535; throws ConfigError naming the setting.
std::string parse_host_port(const Setting& s) {
  const auto colon = s.value.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 == s.value.size()) {
    throw ConfigError(s.name + ": expected HOST:PORT, got '" + s.value + "'");
  }
  parse_integer({s.name, s.value.substr(colon + 1)}, 0, 65535);
  return s.value;
}

/// One of `choices`; throws ConfigError listing them.
std::string parse_choice(const Setting& s, const std::vector<std::string>& choices) {
  if (std::find(choices.begin(), choices.end(), s.value) != choices.end()) return s.value;
  std::string listed;
  for (const auto& choice : choices) listed += (listed.empty() ? "" : ", ") + choice;
  throw ConfigError(s.name + ": unknown value '" + s.value + "' (" + listed + ")");
}

struct Option {
  std::string flag;
  std::string value_hint;
  std::string help;
  std::function<void(ServerConfig&, const Setting&)> apply;
  std::function<std::string(const ServerConfig&)> show;
};

const std::vector<Option>& options() {
  static const std::vector<Option> kTable = {
      {"--listen", "HOST:PORT", "address to listen on; port 0 picks a free port",
       [](ServerConfig& c, const Setting& s) { c.listen = parse_host_port(s); },
       [](const ServerConfig& c) { return c.listen; }},
      {"--http-listen", "HOST:PORT",
       "serve the browser viewer (HTTP, WebSocket) on this address; port 0 picks a free port",
       [](ServerConfig& c, const Setting& s) { c.http_listen = parse_host_port(s); },
       [](const ServerConfig& c) { return c.http_listen.empty() ? std::string("off") : c.http_listen; }},
      {"--drain-deadline-ms", "MS", "on SIGTERM/SIGINT, time running streams get to finish",
       [](ServerConfig& c, const Setting& s) { c.drain_deadline_ms = parse_integer(s, 0, 3'600'000); },
       [](const ServerConfig& c) { return std::to_string(c.drain_deadline_ms); }},
      {"--max-streams", "N", "concurrent Animate and Subscribe streams",
       [](ServerConfig& c, const Setting& s) { c.max_streams = parse_count(s, 1); },
       [](const ServerConfig& c) { return std::to_string(c.max_streams); }},
      {"--max-sessions", "N", "named sessions held at once (live or retained)",
       [](ServerConfig& c, const Setting& s) { c.max_sessions = parse_count(s, 0); },
       [](const ServerConfig& c) { return std::to_string(c.max_sessions); }},
      {"--max-subscribers-per-session", "N", "concurrent subscribers of one session",
       [](ServerConfig& c, const Setting& s) { c.max_subscribers_per_session = parse_count(s, 0); },
       [](const ServerConfig& c) { return std::to_string(c.max_subscribers_per_session); }},
      {"--max-phonemes", "N", "phonemes per utterance",
       [](ServerConfig& c, const Setting& s) { c.max_phonemes = parse_count(s, 1); },
       [](const ServerConfig& c) { return std::to_string(c.max_phonemes); }},
      {"--max-utterance-ms", "MS", "utterance length (end of the last phoneme)",
       [](ServerConfig& c, const Setting& s) { c.max_utterance_ms = parse_integer(s, 1, 86'400'000); },
       [](const ServerConfig& c) { return std::to_string(c.max_utterance_ms); }},
      {"--max-message-bytes", "BYTES", "largest request message",
       [](ServerConfig& c, const Setting& s) { c.max_message_bytes = parse_count(s, 1024); },
       [](const ServerConfig& c) { return std::to_string(c.max_message_bytes); }},
      {"--transport-memory-bytes", "BYTES",
       "gRPC's memory quota for all connections' buffers and calls (0: none; unset: 2 x --max-message-bytes "
       "+ 4 MiB + 8 KiB per call in progress and 1024 more, resized as calls come and go)",
       [](ServerConfig& c, const Setting& s) {
         c.transport_memory_bytes = static_cast<std::size_t>(parse_integer(s, 0, std::int64_t{1} << 40));
       },
       [](const ServerConfig& c) {
         return c.transport_memory_bytes ? std::to_string(*c.transport_memory_bytes) : std::string("unset");
       }},
      {"--max-session-audio-bytes", "BYTES",
       "the sound all sessions keep together for the viewer's /audio (Speak's voice, attached WAVs); "
       "an attachment beyond it is RESOURCE_EXHAUSTED",
       [](ServerConfig& c, const Setting& s) { c.max_session_audio_bytes = parse_count(s, 0); },
       [](const ServerConfig& c) { return std::to_string(c.max_session_audio_bytes); }},
      {"--replay-frames", "N", "frames a session keeps for subscribers that start from the beginning",
       [](ServerConfig& c, const Setting& s) { c.replay_frames = parse_count(s, 0); },
       [](const ServerConfig& c) { return std::to_string(c.replay_frames); }},
      {"--subscriber-queue-frames", "N",
       "frames a subscriber may have waiting before it is cut off (RESOURCE_EXHAUSTED)",
       [](ServerConfig& c, const Setting& s) { c.subscriber_queue_frames = parse_count(s, 1); },
       [](const ServerConfig& c) { return std::to_string(c.subscriber_queue_frames); }},
      {"--max-listen-ms", "MS", "audio one Listen stream may carry (a live voice for hours; a recording whole)",
       [](ServerConfig& c, const Setting& s) { c.max_listen_ms = parse_integer(s, 1, 604'800'000); },
       [](const ServerConfig& c) { return std::to_string(c.max_listen_ms); }},
      {"--listen-threads", "N", "threads that run the speech recognisers of Listen streams, 0 to 256 (0: one per core)",
       [](ServerConfig& c, const Setting& s) { c.listen_threads = static_cast<std::size_t>(parse_integer(s, 0, 256)); },
       [](const ServerConfig& c) { return std::to_string(c.listen_threads); }},
      {"--face-threads", "N", "threads that run the physics face for mesh streams, 0 to 256 (0: one per core)",
       [](ServerConfig& c, const Setting& s) { c.face_threads = static_cast<std::size_t>(parse_integer(s, 0, 256)); },
       [](const ServerConfig& c) { return std::to_string(c.face_threads); }},
      {"--face-priority", "PRIORITY",
       "scheduling of the face threads: idle (only CPU time nothing else wants), low (nice 10) or normal",
       [](ServerConfig& c, const Setting& s) {
         static const std::vector<std::string> kPriorities = {"idle", "low", "normal"};
         if (std::find(kPriorities.begin(), kPriorities.end(), s.value) == kPriorities.end()) {
           throw ConfigError(s.name + ": unknown priority '" + s.value + "' (idle, low or normal)");
         }
         c.face_priority = s.value;
       },
       [](const ServerConfig& c) { return c.face_priority; }},
      {"--max-mesh-streams-per-face-thread", "N",
       "mesh work admitted per face thread, in level-1 30 fps streams (others weigh their CPU need), 0 to 1000",
       [](ServerConfig& c, const Setting& s) {
         c.max_mesh_streams_per_face_thread = static_cast<std::size_t>(parse_integer(s, 0, 1000));
       },
       [](const ServerConfig& c) { return std::to_string(c.max_mesh_streams_per_face_thread); }},
      {"--mesh-max-lag-ms", "MS",
       "a mesh stream whose face falls further behind real time ends with DEADLINE_EXCEEDED, 1 to 3600000",
       [](ServerConfig& c, const Setting& s) { c.mesh_max_lag_ms = parse_integer(s, 1, 3'600'000); },
       [](const ServerConfig& c) { return std::to_string(c.mesh_max_lag_ms); }},
      {"--stalled-subscriber-ms", "MS",
       "a subscriber cut off for falling behind that has stopped reading is cancelled after this long",
       [](ServerConfig& c, const Setting& s) { c.stalled_subscriber_ms = parse_integer(s, 1, 3'600'000); },
       [](const ServerConfig& c) { return std::to_string(c.stalled_subscriber_ms); }},
      {"--session-retention-ms", "MS", "how long a finished session stays joinable",
       [](ServerConfig& c, const Setting& s) { c.session_retention_ms = parse_integer(s, 0, 86'400'000); },
       [](const ServerConfig& c) { return std::to_string(c.session_retention_ms); }},
      {"--log-level", "LEVEL", "trace, debug, info, warn, error or off",
       [](ServerConfig& c, const Setting& s) {
         static const std::vector<std::string> kLevels = {"trace", "debug", "info", "warn", "error", "off"};
         if (std::find(kLevels.begin(), kLevels.end(), s.value) == kLevels.end()) {
           throw ConfigError(s.name + ": unknown level '" + s.value + "' (trace, debug, info, warn, error or off)");
         }
         c.log_level = s.value;
       },
       [](const ServerConfig& c) { return c.log_level; }},
      {"--log-format", "FORMAT", "text (spdlog lines) or json (one object per line)",
       [](ServerConfig& c, const Setting& s) {
         c.log_format = parse_choice(s, {"text", "json"});
       },
       [](const ServerConfig& c) { return c.log_format; }},
      {"--metrics-listen", "HOST:PORT", "serve Prometheus metrics over HTTP at /metrics here (\"\" = off)",
       [](ServerConfig& c, const Setting& s) { c.metrics_listen = s.value.empty() ? "" : parse_host_port(s); },
       [](const ServerConfig& c) { return c.metrics_listen.empty() ? std::string("off") : c.metrics_listen; }},
      {"--model", "NAME=FILE", "load an extra articulation model (repeatable)",
       [](ServerConfig& c, const Setting& s) {
         const auto eq = s.value.find('=');
         if (eq == std::string::npos || eq == 0 || eq + 1 == s.value.size()) {
           throw ConfigError(s.name + ": expected NAME=FILE, got '" + s.value + "'");
         }
         c.models.push_back({s.value.substr(0, eq), s.value.substr(eq + 1)});
       },
       [](const ServerConfig&) { return std::string("none"); }},
      {"--replica-name", "NAME", "this replica's name in errors about sessions it does not hold (a pod or host name)",
       [](ServerConfig& c, const Setting& s) { c.replica_name = s.value; },
       [](const ServerConfig&) { return std::string("host name and listen address"); }},
      {"--tls-cert", "FILE", "PEM certificate chain: serve TLS (needs --tls-key; reloaded on SIGHUP)",
       [](ServerConfig& c, const Setting& s) { c.tls_cert = s.value; },
       [](const ServerConfig&) { return std::string("none: plaintext"); }},
      {"--tls-key", "FILE", "PEM private key of --tls-cert (reloaded on SIGHUP)",
       [](ServerConfig& c, const Setting& s) { c.tls_key = s.value; },
       [](const ServerConfig&) { return std::string("none"); }},
      {"--tls-client-ca", "FILE", "PEM CA bundle: require client certificates it signed (mTLS; reloaded on SIGHUP)",
       [](ServerConfig& c, const Setting& s) { c.tls_client_ca = s.value; },
       [](const ServerConfig&) { return std::string("none: no client certificates"); }},
      {"--api-keys", "FILE", "JSON file of hashed API keys, their tenants and quotas (reloaded on SIGHUP)",
       [](ServerConfig& c, const Setting& s) { c.api_keys = s.value; },
       [](const ServerConfig&) { return std::string("none: open to every caller"); }},
  };
  return kTable;
}

const Option* find_option(std::string_view flag) {
  for (const Option& option : options()) {
    if (option.flag == flag) return &option;
  }
  return nullptr;
}

std::string json_scalar(const nlohmann::json& value, const std::string& key) {
  if (value.is_string()) return value.get<std::string>();
  if (value.is_number_integer()) return std::to_string(value.get<std::int64_t>());
  throw ConfigError(key + ": expected a string or an integer");
}

std::vector<Setting> read_config_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError("--config: cannot open '" + path + "'");
  std::stringstream text;
  text << in.rdbuf();
  const auto json = nlohmann::json::parse(text.str(), nullptr, false);
  if (json.is_discarded() || !json.is_object()) {
    throw ConfigError("--config: '" + path + "' is not a JSON object");
  }
  std::vector<Setting> settings;
  for (const auto& [key, value] : json.items()) {
    const std::string where = path + ": key \"" + key + "\"";
    if (!find_option("--" + key) || key == "config") throw ConfigError(where + ": unknown setting");
    if (key == "model" && value.is_object()) {
      for (const auto& [name, file] : value.items()) {
        settings.push_back({where, name + "=" + json_scalar(file, where)});
      }
    } else if (value.is_array()) {
      for (const auto& item : value) settings.push_back({where, json_scalar(item, where)});
    } else {
      settings.push_back({where, json_scalar(value, where)});
    }
  }
  return settings;
}

std::string option_of(const std::string& where) {
  const auto quote = where.rfind("key \"");
  if (quote == std::string::npos) return where;
  const auto start = quote + 5;
  return "--" + where.substr(start, where.find('"', start) - start);
}

/// Settings from LIPSYNCD_* variables, named after the variable in errors.
std::vector<Setting> read_environment(const Environment& environment, std::vector<const Option*>& applies_to) {
  std::vector<Setting> settings;
  if (!environment) return settings;
  for (const Option& option : options()) {
    const std::string variable = environment_variable(option.flag);
    const std::optional<std::string> value = environment(variable);
    if (!value) continue;
    if (option.flag == "--model") {  // a comma-separated list of NAME=FILE
      std::size_t begin = 0;
      while (begin <= value->size()) {
        const std::size_t comma = std::min(value->find(',', begin), value->size());
        settings.push_back({variable, value->substr(begin, comma - begin)});
        applies_to.push_back(&option);
        begin = comma + 1;
      }
      continue;
    }
    settings.push_back({variable, *value});
    applies_to.push_back(&option);
  }
  return settings;
}

/// The flags of `args` taken apart (lipsync::options, CLI11), every value as written;
/// ConfigError for an unknown flag, a stray word or a missing value.
options::ParsedArguments parse_flags(const std::vector<std::string>& args) {
  static const std::vector<options::OptionSpec> kSpecs = [] {
    std::vector<options::OptionSpec> table = {{"config", 0, "FILE", "", ""}};
    for (const Option& option : options()) {
      table.push_back({std::string_view(option.flag).substr(2), 0, option.value_hint, option.help, ""});
    }
    return table;
  }();
  try {
    options::ParsedArguments parsed = options::parse_arguments(args, kSpecs);
    if (!parsed.positional().empty() && !parsed.help()) {
      throw ConfigError(parsed.positional().front() + ": unknown flag (see --help)");
    }
    return parsed;
  } catch (const options::ArgumentError& error) {
    if (error.kind() == options::ArgumentError::Kind::missing_value)
      throw ConfigError(error.option() + ": missing value");
    const std::string& word = error.argument();
    throw ConfigError(word.substr(0, word.find('=')) + ": unknown flag (see --help)");
  }
}

}  // namespace

Environment process_environment() {
  return [](const std::string& name) -> std::optional<std::string> {
    const char* value = std::getenv(name.c_str());
    if (value == nullptr) return std::nullopt;
    return std::string(value);
  };
}

std::string environment_variable(const std::string& flag) {
  std::string name = "LIPSYNCD_";
  for (const char c : flag.substr(flag.rfind("--", 0) == 0 ? 2 : 0)) {
    name += c == '-' ? '_' : static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  return name;
}

CommandLine parse_command_line(const std::vector<std::string>& args, const Environment& environment) {
  CommandLine result;
  const options::ParsedArguments parsed = parse_flags(args);
  if (parsed.help()) {
    result.help = true;
    return result;
  }
  std::vector<Setting> flags;
  for (const Option& option : options()) {
    for (const std::string& value : parsed.values(option.flag.substr(2))) flags.push_back({option.flag, value});
  }
  std::string config_path = parsed.value("config").value_or("");
  if (config_path.empty() && environment) {
    config_path = environment(environment_variable("--config")).value_or("");
  }
  std::vector<const Option*> environment_options;
  const std::vector<Setting> from_environment = read_environment(environment, environment_options);
  std::vector<Setting> settings;
  if (!config_path.empty()) settings = read_config_file(config_path);
  const bool flags_have_models =
      std::any_of(flags.begin(), flags.end(), [](const Setting& s) { return s.name == "--model"; });
  const bool environment_has_models = std::any_of(environment_options.begin(), environment_options.end(),
                                                  [](const Option* o) { return o->flag == "--model"; });
  // Each source overrides the one before; a list of models replaces the list before it.
  for (const Setting& setting : settings) {
    if ((flags_have_models || environment_has_models) && option_of(setting.name) == "--model") continue;
    find_option(option_of(setting.name))->apply(result.config, setting);
  }
  for (std::size_t i = 0; i < from_environment.size(); ++i) {
    // A flag replaces its variable, even one that would not parse (a container's default).
    const std::string& flag = environment_options[i]->flag;
    if (std::any_of(flags.begin(), flags.end(), [&](const Setting& s) { return s.name == flag; })) continue;
    environment_options[i]->apply(result.config, from_environment[i]);
  }
  for (const Setting& setting : flags) find_option(setting.name)->apply(result.config, setting);
  return result;
}

std::string help_text() {
  const ServerConfig defaults;
  std::ostringstream out;
  out << "lipsyncd: coarticulated lip-sync animation over gRPC (lipsync.v1.LipSync)\n\n"
      << "Usage: lipsyncd [--config FILE] [flags]\n"
      << "       lipsyncd --hash-key < KEY   (prints the key's SHA-256, as --api-keys files hold it)\n\n"
      << "  --config FILE  JSON object with any of the settings below (keys without the\n"
      << "                 dashes); flags given on the command line override it\n"
      << "Every setting can also come from an environment variable, LIPSYNCD_ and the flag in\n"
      << "capitals with '_' for '-' (LIPSYNCD_LISTEN, LIPSYNCD_MAX_STREAMS, LIPSYNCD_CONFIG;\n"
      << "LIPSYNCD_MODEL=NAME=FILE,NAME=FILE): over the file, under the flags.\n\n";
  for (const Option& option : options()) {
    std::string left = "  " + option.flag + " " + option.value_hint;
    if (left.size() < 36) left.resize(36, ' ');
    out << left << " " << option.help << " (default: " << option.show(defaults) << ")\n";
  }
  out << "\nOn SIGTERM or SIGINT the server closes its listener (balancers and clients go to another\n"
      << "replica), lets running streams finish for --drain-deadline-ms, cancels the rest and exits 0.\n"
      << "SIGHUP re-reads the configuration: the log level changes at once, the TLS files and the\n"
      << "API key file are read again (a bad one is logged and the old one kept); other changes are\n"
      << "logged as needing a restart. Bad flags exit 2; a bad model file exits 1.\n";
  return out.str();
}

}  // namespace lipsync::server
