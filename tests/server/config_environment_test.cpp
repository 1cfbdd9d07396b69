// lipsyncd's configuration from the environment (LIPSYNCD_*): every flag has its variable,
// flags beat the environment, which beats the --config file; a bad value names its variable.
// Through the binary: LIPSYNCD_LISTEN alone starts it, SIGHUP re-reads the configuration.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <map>
#include <regex>

#include "../support/child_process.hpp"
#include "../support/server_harness.hpp"
#include "lipsync/server/config.hpp"

namespace lipsync::server {
namespace {

using ::testing::HasSubstr;

Environment environment_of(std::map<std::string, std::string> variables) {
  return [variables = std::move(variables)](const std::string& name) -> std::optional<std::string> {
    const auto found = variables.find(name);
    if (found == variables.end()) return std::nullopt;
    return found->second;
  };
}

// A valid value for every flag; a flag missing here fails EveryFlagHasAnEnvironmentVariable.
const std::map<std::string, std::string> kValues = {
    {"--listen", "127.0.0.1:6001"},
    {"--drain-deadline-ms", "1234"},
    {"--max-streams", "17"},
    {"--max-sessions", "18"},
    {"--max-subscribers-per-session", "19"},
    {"--max-phonemes", "20"},
    {"--max-utterance-ms", "21"},
    {"--max-message-bytes", "4096"},
    {"--replay-frames", "22"},
    {"--subscriber-queue-frames", "23"},
    {"--face-threads", "3"},
    {"--face-priority", "low"},
    {"--max-mesh-streams-per-face-thread", "5"},
    {"--mesh-max-lag-ms", "1500"},
    {"--stalled-subscriber-ms", "24"},
    {"--session-retention-ms", "25"},
    {"--log-level", "debug"},
    {"--model", "mine=/m.json"},
    {"--replica-name", "pod-7"},
    {"--tls-cert", "/etc/lipsyncd/cert.pem"},
    {"--tls-key", "/etc/lipsyncd/key.pem"},
    {"--tls-client-ca", "/etc/lipsyncd/clients.pem"},
    {"--api-keys", "/etc/lipsyncd/keys.json"},
    {"--http-listen", "127.0.0.1:6002"},
    {"--log-format", "json"},
    {"--metrics-listen", "127.0.0.1:9464"},
    {"--transport-memory-bytes", "1048576"},
    {"--max-session-audio-bytes", "1048577"},
    {"--max-listen-ms", "3600001"},
    {"--listen-threads", "3"},
};

std::vector<std::string> flags_in_help() {
  std::vector<std::string> flags;
  const std::string help = help_text();
  const std::regex flag_line(R"(\n  (--[a-z-]+) [A-Z])");
  for (auto it = std::sregex_iterator(help.begin(), help.end(), flag_line); it != std::sregex_iterator(); ++it) {
    if ((*it)[1] != "--config") flags.push_back((*it)[1]);
  }
  return flags;
}

TEST(ConfigEnvironment, EveryFlagHasAnEnvironmentVariableThatSetsTheSameValue) {
  const std::vector<std::string> flags = flags_in_help();
  ASSERT_GE(flags.size(), 17u);
  for (const std::string& flag : flags) {
    ASSERT_TRUE(kValues.count(flag)) << flag << " has no test value here";
    const std::string& value = kValues.at(flag);
    const ServerConfig from_flag = parse_command_line({flag, value}).config;
    const ServerConfig from_environment =
        parse_command_line({}, environment_of({{environment_variable(flag), value}})).config;
    EXPECT_TRUE(from_flag == from_environment) << flag << " and " << environment_variable(flag);
    EXPECT_FALSE(from_environment == ServerConfig{}) << environment_variable(flag) << " changed nothing";
  }
  EXPECT_EQ(environment_variable("--max-subscribers-per-session"), "LIPSYNCD_MAX_SUBSCRIBERS_PER_SESSION");
}

TEST(ConfigEnvironment, FlagsBeatTheEnvironmentWhichBeatsTheFile) {
  const auto dir = testing::make_temp_dir("lipsyncd-config-");
  testing::write_text(dir / "lipsyncd.json",
                      R"({"max-streams": 5, "max-sessions": 50, "log-level": "error", "model": {"file": "/f.json"}})");
  const auto environment = environment_of({{"LIPSYNCD_CONFIG", (dir / "lipsyncd.json").string()},
                                           {"LIPSYNCD_MAX_STREAMS", "6"},
                                           {"LIPSYNCD_LOG_LEVEL", "warn"},
                                           {"LIPSYNCD_MODEL", "a=/a.json,b=/b.json"}});
  const ServerConfig config = parse_command_line({"--log-level", "debug"}, environment).config;
  EXPECT_EQ(config.max_sessions, 50u);   // the file (named by LIPSYNCD_CONFIG)
  EXPECT_EQ(config.max_streams, 6u);     // the environment over the file
  EXPECT_EQ(config.log_level, "debug");  // the flag over the environment
  EXPECT_EQ(config.models, (std::vector<ModelFile>{{"a", "/a.json"}, {"b", "/b.json"}}));  // replaces the file's
  const ServerConfig flagged = parse_command_line({"--model", "c=/c.json"}, environment).config;
  EXPECT_EQ(flagged.models, (std::vector<ModelFile>{{"c", "/c.json"}}));
  std::filesystem::remove_all(dir);
}

TEST(ConfigEnvironment, ABadValueNamesTheVariableAndTheValue) {
  try {
    parse_command_line({}, environment_of({{"LIPSYNCD_MAX_STREAMS", "lots"}}));
    FAIL() << "accepted LIPSYNCD_MAX_STREAMS=lots";
  } catch (const ConfigError& error) {
    EXPECT_THAT(error.what(), HasSubstr("LIPSYNCD_MAX_STREAMS: expected an integer, got 'lots'"));
  }
  EXPECT_THROW(parse_command_line({}, environment_of({{"LIPSYNCD_MODEL", "a=/a.json,"}})), ConfigError);
  EXPECT_THAT(help_text(), HasSubstr("LIPSYNCD_LISTEN"));
}

std::string flag_error_of(const std::vector<std::string>& args) {
  try {
    parse_command_line(args);
  } catch (const ConfigError& error) {
    return error.what();
  }
  return "accepted";
}

// The flags go through lipsync::options (CLI11), the parser lipsync uses; the words stay lipsyncd's.
TEST(ConfigFlags, MistakesNameTheFlagInLipsyncdsWords) {
  EXPECT_EQ(flag_error_of({"--bogus", "1"}), "--bogus: unknown flag (see --help)");
  EXPECT_EQ(flag_error_of({"--bogus=1"}), "--bogus: unknown flag (see --help)");
  EXPECT_EQ(flag_error_of({"stray"}), "stray: unknown flag (see --help)");
  EXPECT_EQ(flag_error_of({"--max-streams", "4", "--listen"}), "--listen: missing value");
  EXPECT_EQ(flag_error_of({"--listen", "--max-streams", "4"}), "--listen: missing value");
  EXPECT_EQ(flag_error_of({"--max-streams=-3"}), "--max-streams: '-3' is out of range (1 to 2147483647)");
}

TEST(ConfigFlags, EqualsFormRepeatedModelsAndEmptyValues) {
  const ServerConfig config =
      parse_command_line({"--max-streams=9", "--model", "a=/a.json", "--model=b=/b.json", "--metrics-listen="}).config;
  EXPECT_EQ(config.max_streams, 9u);
  EXPECT_EQ(config.models, (std::vector<ModelFile>{{"a", "/a.json"}, {"b", "/b.json"}}));
  EXPECT_EQ(config.metrics_listen, "");
  EXPECT_EQ(parse_command_line({"--max-streams", "1", "--max-streams", "2"}).config.max_streams, 2u);
}

TEST(ConfigEnvironment, WithoutAnEnvironmentNothingIsRead) {
  ::setenv("LIPSYNCD_MAX_STREAMS", "3", 1);
  EXPECT_EQ(parse_command_line({}).config.max_streams, ServerConfig{}.max_streams);
  EXPECT_EQ(parse_command_line({}, process_environment()).config.max_streams, 3u);
  ::unsetenv("LIPSYNCD_MAX_STREAMS");
}

// --- the binary ----------------------------------------------------------------------------

TEST(LipsyncdEnvironment, TheBinaryTakesItsSettingsFromTheEnvironmentAndAFlagWins) {
  const auto dir = testing::make_temp_dir("lipsyncd-env-");
  ::setenv("LIPSYNCD_LISTEN", "127.0.0.1:0", 1);
  ::setenv("LIPSYNCD_MAX_STREAMS", "-3", 1);
  const testing::RunResult bad = testing::run_program({LIPSYNCD_PATH}, dir, dir);
  EXPECT_EQ(bad.status, 2);
  EXPECT_THAT(bad.err, HasSubstr("LIPSYNCD_MAX_STREAMS: '-3' is out of range (1 to 2147483647)"));
  {
    testing::ChildProcess server({LIPSYNCD_PATH, "--max-streams", "4"}, dir, dir / "out", dir / "err");
    const std::string address = testing::wait_for_listening_address(dir / "out");
    EXPECT_THAT(address, ::testing::MatchesRegex(R"(127\.0\.0\.1:[1-9][0-9]*)")) << testing::read_text(dir / "err");
  }
  ::unsetenv("LIPSYNCD_LISTEN");
  ::unsetenv("LIPSYNCD_MAX_STREAMS");
  std::filesystem::remove_all(dir);
}

TEST(LipsyncdEnvironment, SighupRereadsTheConfigurationAndKeepsServing) {
  const auto dir = testing::make_temp_dir("lipsyncd-hup-");
  const auto file = dir / "lipsyncd.json";
  testing::write_text(file, R"({"listen": "127.0.0.1:0", "log-level": "info"})");
  testing::ChildProcess server({LIPSYNCD_PATH, "--config", file.string()}, dir, dir / "out", dir / "err");
  const std::string address = testing::wait_for_listening_address(dir / "out");
  ASSERT_FALSE(address.empty()) << testing::read_text(dir / "err");
  testing::write_text(file, R"({"listen": "127.0.0.1:0", "log-level": "info", "max-streams": 9})");
  server.signal(SIGHUP);
  ASSERT_TRUE(harness::eventually([&] {
    return testing::read_text(dir / "err").find("next restart") != std::string::npos;
  })) << testing::read_text(dir / "err");
  testing::write_text(file, R"({"listen": "127.0.0.1:0", "log-level": "bogus"})");
  server.signal(SIGHUP);
  ASSERT_TRUE(harness::eventually([&] {
    return testing::read_text(dir / "err").find("not reloaded: " + file.string()) != std::string::npos;
  })) << testing::read_text(dir / "err");
  auto stub = v1::LipSync::NewStub(harness::connect(address));
  const harness::Received still = harness::animate(*stub, harness::whole({}, harness::utterance(5, 2), 5));
  EXPECT_TRUE(still.status.ok()) << still.status.error_message();
  server.terminate();
  EXPECT_EQ(server.wait(), 0);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace lipsync::server
