// `lipsync subscribe SESSION`: follows the frames of a session that another
// client is streaming to lipsyncd, and writes them once the producer has
// finished (all or nothing: a session that fails leaves no file), named as the
// producer's TrackHeader names them (the server's model, channels and ARKit).
#include <array>
#include <chrono>
#include <iostream>
#include <thread>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "files.hpp"
#include "network.hpp"
#include "pipeline.hpp"
#include "received_track_writer.hpp"

namespace lipsync::cli {
namespace {

/// --timeout: a session may run for hours.
constexpr IntSetting kFollowTimeoutSetting = {1, 86'400, 3600};

constexpr auto kOptions =
    join(kConnectionOptions,
         std::to_array<OptionSpec>({
             kTrackOutputOption,
             kTrackFormatOption,
             {"from-beginning", 0, "", "replay the frames the server still holds, then follow (the default)", ""},
             kFromNowOption,
             kWaitOption,
             kTimeoutOption<"give up when the session has not finished after S seconds", kFollowTimeoutSetting>,
         }));

constexpr std::string_view kUsage = "lipsync subscribe SESSION [options]";
constexpr std::string_view kDescription =
    "Follows the frames of SESSION (published by 'lipsync stream --session SESSION' or any\n"
    "Animate stream with a session name) until its producer finishes, then writes them\n"
    "with the channel and ARKit names of the server's model that the session uses.";

}  // namespace

int run_subscribe(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "subscribe");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (arguments.positional().size() != 1 || arguments.positional().front().empty()) {
    throw UsageError("subscribe needs exactly one SESSION name (see 'lipsync subscribe --help')");
  }
  const std::string& session = arguments.positional().front();
  const std::string address = server_address(arguments);
  const std::string output = arguments.value("output").value_or("-");
  const TrackFormat format = parse_track_format_option(arguments.value("format").value_or("json"));
  if (arguments.flag("from-beginning") && arguments.flag("from-now")) {
    throw UsageError("choose one of --from-beginning and --from-now");
  }
  const auto start = subscribe_start(arguments);
  SessionWait wait(arguments);
  const int timeout_s = parse_setting_option(arguments, "timeout", kFollowTimeoutSetting);

  client::ClientOptions client_options = connection_options(arguments);
  client_options.stream_timeout = std::chrono::seconds(timeout_s);
  const client::AnimationClient connection(address, client_options);
  connection.wait_connected();
  wait.start();
  for (;;) {
    try {
      const client::ReceivedTrack received = connection.subscribe(session, start);
      write_received_track(received, format, output, "session '" + session + "'");
      return 0;
    } catch (const client::CallError& error) {
      if (!wait.asks_again(error.code())) throw;
      std::this_thread::sleep_for(SessionWait::kPause);
    }
  }
}

}  // namespace lipsync::cli
