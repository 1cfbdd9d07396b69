// lipsyncd: the gRPC lip-sync animation server.
//
// Reads the configuration (exit 2 on a bad flag, 1 on a bad model file or an
// address it cannot bind), starts the server, prints
// "lipsyncd listening on HOST:PORT" on stdout, and waits for SIGTERM or SIGINT
// in sigwait (the signals are blocked in every thread, so no handler runs in
// an arbitrary thread). It then drains: no new calls, running streams get
// --drain-deadline-ms to finish, the rest are cancelled, exit 0.
#include <csignal>
#include <cstdio>
#include <iostream>
#include <pthread.h>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include "lipsync/error.hpp"
#include "lipsync/server/config.hpp"
#include "lipsync/server/server.hpp"

int main(int argc, char** argv) {
  using namespace lipsync::server;
  CommandLine command_line;
  try {
    command_line = parse_command_line(std::vector<std::string>(argv + 1, argv + argc));
  } catch (const ConfigError& error) {
    std::cerr << "lipsyncd: " << error.what() << "\n";
    return 2;
  }
  if (command_line.help) {
    std::cout << help_text();
    return 0;
  }
  const ServerConfig& config = command_line.config;
  spdlog::set_default_logger(spdlog::stderr_color_mt("lipsyncd"));
  spdlog::set_level(spdlog::level::from_str(config.log_level));

  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  std::unique_ptr<Server> server;
  try {
    server = std::make_unique<Server>(config);
  } catch (const lipsync::InputError& error) {
    std::cerr << "lipsyncd: " << error.what() << "\n";
    return 1;
  } catch (const std::exception& error) {
    std::cerr << "lipsyncd: " << error.what() << "\n";
    return 1;
  }
  std::cout << "lipsyncd listening on " << server->address() << std::endl;
  spdlog::info("listening on {}", server->address());

  int signal_number = 0;
  sigwait(&signals, &signal_number);
  spdlog::info("{} received: draining for up to {} ms ({} streams open)",
               signal_number == SIGTERM ? "SIGTERM" : "SIGINT", config.drain_deadline_ms,
               server->active_streams());
  server->shutdown(std::chrono::milliseconds(config.drain_deadline_ms));
  spdlog::info("stopped");
  return 0;
}
