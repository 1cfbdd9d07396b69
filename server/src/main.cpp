// lipsyncd: the gRPC lip-sync animation server.
//
// Reads the configuration from flags, LIPSYNCD_* variables and --config (exit 2
// on a bad setting, 1 on a bad model file or an address it cannot bind), starts
// the server, prints "lipsyncd listening on HOST:PORT" on stdout (and, with --http-listen,
// "lipsyncd viewer on http://HOST:PORT/view"), and waits for
// SIGTERM, SIGINT or SIGHUP in sigwait (the signals are blocked in every
// thread, so no handler runs in an arbitrary thread). SIGHUP re-reads the
// configuration (systemd's ExecReload): the log level applies at once, other
// changes are logged as needing a restart. SIGTERM and SIGINT drain: the
// listener closes (GOAWAY), running streams get --drain-deadline-ms to finish,
// the rest are aborted (ABORTED), and the process exits 0 at once (_Exit: see
// the end of main). SIGHUP also re-reads the TLS files and the API key file
// (server.hpp, reload_credentials).
//
// `lipsyncd --hash-key` reads an API key from standard input and prints its
// SHA-256, the form the key file holds (tenants.hpp).
#include <absl/synchronization/mutex.h>
#include <grpc/support/log.h>
#include <malloc.h>
#include <pthread.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "lipsync/error.hpp"
#include "lipsync/server/config.hpp"
#include "lipsync/server/server.hpp"
#include "transport/tenants.hpp"

namespace {

/// SIGHUP: reads flags, environment and file again; applies what can change while running.
void reload(const std::vector<std::string>& args, lipsync::server::ServerConfig& running) {
  using namespace lipsync::server;
  try {
    ServerConfig next = parse_command_line(args, process_environment()).config;
    spdlog::set_level(spdlog::level::from_str(next.log_level));
    if (next.log_level != running.log_level) spdlog::info("SIGHUP: log level now {}", next.log_level);
    running.log_level = next.log_level;
    if (next == running) {
      spdlog::info("SIGHUP: configuration re-read");
    } else {
      spdlog::warn("SIGHUP: settings other than log-level changed: they take effect at the next restart");
    }
  } catch (const ConfigError& error) {
    spdlog::error("SIGHUP: configuration not reloaded: {}", error.what());
  }
}

/// `lipsyncd --hash-key`: the SHA-256 of the API key on standard input, the form the key file holds.
int print_key_hash() {
  std::string key;
  std::getline(std::cin, key);
  if (key.empty()) {
    std::cerr << "lipsyncd: --hash-key: no key on standard input (echo -n KEY | lipsyncd --hash-key)\n";
    return 2;
  }
  std::cout << lipsync::server::sha256_hex(key) << "\n";
  return 0;
}

/// spdlog's logger on stderr at the configured level, with gRPC core's own messages (a failed TLS
/// handshake, for one) through it too, so that with --log-format json every line on stderr is one
/// JSON object; gRPC's verbosity (GRPC_VERBOSITY, errors by default) still decides which of them
/// are written.
void start_logging(const lipsync::server::ServerConfig& config) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("lipsyncd"));
  gpr_set_log_function([](gpr_log_func_args* entry) {
    const spdlog::level::level_enum level = entry->severity == GPR_LOG_SEVERITY_ERROR  ? spdlog::level::err
                                            : entry->severity == GPR_LOG_SEVERITY_INFO ? spdlog::level::info
                                                                                       : spdlog::level::debug;
    spdlog::log(level, "grpc: {} ({}:{})", entry->message, entry->file, entry->line);
  });
  spdlog::set_level(spdlog::level::from_str(config.log_level));
}

/// The process-wide settings a long-running server wants: the priority the face threads get back
/// at shutdown, memory given back after a burst, abseil's deadlock detection off.
void tune_process() {
  // Lets the shutdown give the face threads their normal priority back (face_workers.hpp):
  // the soft RLIMIT_NICE as high as the hard limit allows.
  if (rlimit nice{}; ::getrlimit(RLIMIT_NICE, &nice) == 0 && nice.rlim_cur < nice.rlim_max) {
    nice.rlim_cur = nice.rlim_max;
    ::setrlimit(RLIMIT_NICE, &nice);
  }

  // Memory given back after a burst (docs/server.md, "Soak"): glibc's mmap threshold stays at
  // 128 kB instead of rising to the largest block freed so far. Otherwise, after one large
  // message (say a 5 MB one refused as too large) later buffers below that size stay in the
  // heap, and resident memory sits 25 to 60 MB higher from then on. MALLOC_MMAP_THRESHOLD_ in
  // the environment still decides when it is set.
  if (std::getenv("MALLOC_MMAP_THRESHOLD_") == nullptr) ::mallopt(M_MMAP_THRESHOLD, 128 * 1024);

  // gRPC's locks are abseil Mutexes, and Debian builds abseil without NDEBUG, which leaves its
  // deadlock detection on: every lock and unlock also maintains a graph of lock order
  // (GraphCycles), about 4 % of the server's instructions per frame (docs/performance.md,
  // "What makes the server cheap"). A debugging aid for abseil's users, not a defence: lipsyncd turns it off.
  absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);
}

/// SIGTERM, SIGINT and SIGHUP blocked in this thread and every thread it starts, for sigwait.
sigset_t block_signals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  return signals;
}

/// The addresses the server listens on, on stdout (for whoever started it) and in the log.
void announce(const lipsync::server::Server& server, const lipsync::server::ServerConfig& config) {
  std::cout << "lipsyncd listening on " << server.address() << std::endl;
  if (const std::string viewer = server.http_address(); !viewer.empty()) {
    std::cout << "lipsyncd viewer on http://" << viewer << "/view" << std::endl;
    spdlog::info("browser viewer on http://{}/view", viewer);
  }
  if (!config.metrics_listen.empty()) std::cout << "lipsyncd metrics on " << server.metrics_address() << std::endl;
  spdlog::info("listening on {}", server.address());
}

/// Reloads on SIGHUP until SIGTERM or SIGINT, then drains and exits 0.
[[noreturn]] void serve_until_stopped(const std::vector<std::string>& args, lipsync::server::ServerConfig& config,
                                      lipsync::server::Server& server, const sigset_t& signals) {
  int signal_number = 0;
  while (sigwait(&signals, &signal_number) == 0 && signal_number == SIGHUP) {
    reload(args, config);
    server.reload_credentials();
  }
  spdlog::info("{} received: draining for up to {} ms ({} streams open)",
               signal_number == SIGTERM ? "SIGTERM" : "SIGINT", config.drain_deadline_ms, server.active_streams());
  server.drain_for_exit(std::chrono::milliseconds(config.drain_deadline_ms));
  spdlog::info("stopped");
  // Every call has ended and the connections had their grace: exit now, without
  // destroying the server. Its destructor would wait for gRPC's teardown and join the
  // face threads, which on a busy machine wait for time slices (face threads at
  // SCHED_IDLE for seconds, if drain_for_exit could not raise their priority): exactly
  // what a server shutting down under load must not wait for.
  spdlog::default_logger()->flush();
  std::cout.flush();
  std::_Exit(0);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace lipsync::server;
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.size() == 1 && args[0] == "--hash-key") return print_key_hash();
  CommandLine command_line;
  try {
    command_line = parse_command_line(args, process_environment());
  } catch (const ConfigError& error) {
    std::cerr << "lipsyncd: " << error.what() << "\n";
    return 2;
  }
  if (command_line.help) {
    std::cout << help_text();
    return 0;
  }
  ServerConfig config = command_line.config;
  start_logging(config);
  tune_process();
  const sigset_t signals = block_signals();

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
  announce(*server, config);
  serve_until_stopped(args, config, *server, signals);
}
