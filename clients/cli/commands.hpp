// The subcommands of `lipsync`. Each takes the words after its name, prints
// to stdout, returns the exit status, and throws UsageError, FileError or
// lipsync::InputError for main() to report.
#pragma once

#include <span>
#include <string_view>

namespace lipsync::cli {

int run_render(std::span<const std::string_view> args);
int run_say(std::span<const std::string_view> args);
int run_align(std::span<const std::string_view> args);
int run_demo(std::span<const std::string_view> args);
int run_model(std::span<const std::string_view> args);
int run_phone_sets(std::span<const std::string_view> args);
int run_voices(std::span<const std::string_view> args);
#ifdef LIPSYNC_WITH_NETWORK
int run_stream(std::span<const std::string_view> args);
int run_speak(std::span<const std::string_view> args);
int run_listen(std::span<const std::string_view> args);
int run_subscribe(std::span<const std::string_view> args);
int run_play(std::span<const std::string_view> args);
int run_loadtest(std::span<const std::string_view> args);
int run_server_models(std::span<const std::string_view> args);
int run_health(std::span<const std::string_view> args);
#endif

}  // namespace lipsync::cli
