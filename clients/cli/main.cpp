// lipsync: the command-line client of lipsyncd. Dispatches to a subcommand
// and turns every failure into one line on stderr and an exit status:
// 0 success, 1 bad input or a file problem, 2 a mistake on the command line.
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <new>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "cli_error.hpp"
#include "commands.hpp"
#include "lipsync/error.hpp"
#ifdef LIPSYNC_WITH_NETWORK
#include "lipsync/client/animation_client.hpp"
#endif

#if defined(__SANITIZE_ADDRESS__)
#define LIPSYNC_ADDRESS_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define LIPSYNC_ADDRESS_SANITIZER 1
#endif
#endif
#ifdef LIPSYNC_ADDRESS_SANITIZER
#include <sanitizer/lsan_interface.h>
#endif

namespace {

using namespace lipsync::cli;

struct Command {
  std::string_view name;
  std::string_view summary;
  int (*run)(std::span<const std::string_view>);
};

constexpr Command kCommands[] = {
    {"render", "render a timed phoneme file to an animation track", run_render},
    {"say", "speak a text with espeak-ng and render its phonemes (track, --wav, --video)", run_say},
    {"align", "align a WAV (with --text) to its phones with PocketSphinx; writes a TextGrid", run_align},
    {"demo", "render the built-in demo utterance to lipsync-demo.json", run_demo},
    {"model", "model dump: print the built-in model (or --model FILE) as JSON", run_model},
    {"phone-sets", "list the built-in phone sets", run_phone_sets},
#ifdef LIPSYNC_WITH_NETWORK
    {"stream", "stream a phoneme file to lipsyncd and write the frames it sends", run_stream},
    {"speak", "have lipsyncd speak a text (Speak) and write the track (and --wav the speech)", run_speak},
    {"subscribe", "follow a lipsyncd session and write its frames", run_subscribe},
    {"play", "play a lipsyncd session in the terminal in real time", run_play},
    {"loadtest", "load-test a lipsyncd on this machine", run_loadtest},
    {"server-models", "list a running lipsyncd's models, or describe one (NAME)", run_server_models},
    {"health", "ask a lipsyncd's gRPC health service whether it serves (exit 0) or not", run_health},
#endif
};

constexpr std::string_view kOverview =
    "lipsync: coarticulated lip-sync animation from timed phonemes.\n"
    "\n"
    "Usage: lipsync COMMAND [options]\n"
    "\n"
    "Commands:\n";

constexpr std::string_view kFooter =
    "\n"
    "Run 'lipsync COMMAND --help' for the options of a command, 'lipsync --version'\n"
    "for the version. Exit status: 0 success, 1 bad input or file, 2 bad command line.\n"
#ifdef LIPSYNC_WITH_NETWORK
    "'model dump' prints a model file on this machine; 'server-models' asks a running\n"
    "lipsyncd (--server HOST:PORT) which models it serves, for 'stream --server-model'.\n"
#endif
    ;

constexpr std::size_t kNameWidth = 15;

void print_overview(std::ostream& out) {
  out << kOverview;
  for (const Command& command : kCommands) {
    out << "  " << command.name << std::string(kNameWidth - command.name.size(), ' ') << command.summary << '\n';
  }
  out << kFooter;
}

int fail(std::string_view message, int status) {
  std::cerr << "lipsync: error: " << message << '\n';
  return status;
}

int dispatch(const std::vector<std::string_view>& args) {
  if (args.empty()) {
    print_overview(std::cerr);
    return kExitUsageError;
  }
  const std::string_view name = args.front();
  if (name == "-h" || name == "--help" || name == "help") {
    print_overview(std::cout);
    return 0;
  }
  if (name == "--version") {
    std::cout << "lipsync " << LIPSYNC_VERSION << '\n';
    return 0;
  }
  for (const Command& command : kCommands) {
    if (command.name == name) return command.run(std::span(args).subspan(1));
  }
  throw UsageError("unknown command '" + std::string(name) + "' (see 'lipsync --help')");
}

/// Runs the command; its status, and every failure as one line on stderr.
int run(const std::vector<std::string_view>& args) {
  try {
    return dispatch(args);
  } catch (const UsageError& error) {
    return fail(error.what(), kExitUsageError);
  } catch (const lipsync::InputError& error) {
    return fail(error.what(), kExitInputError);
  } catch (const FileError& error) {
    return fail(error.what(), kExitInputError);
#ifdef LIPSYNC_WITH_NETWORK
  } catch (const lipsync::client::CallError& error) {
    return fail(error.what(), kExitInputError);
#endif
  } catch (const std::bad_alloc&) {
    return fail("out of memory", kExitInputError);
  } catch (const std::exception& error) {
    return fail(std::string("internal error: ") + error.what(), kExitInputError);
  }
}

/// Ends the process once the command's output is flushed, without exit handlers.
/// gRPC's threads may still be busy with a connection the command has given up
/// on (a TLS handshake retried after --timeout, say) while the exit handlers
/// run, and OpenSSL's frees what such a thread uses: `server-models --ca` against
/// a server that wants a client certificate died with SIGSEGV after printing its
/// error in 2 of 60 runs. Everything the command wrote is closed by now (its
/// files by their writers, stdout and stderr here), and lipsyncd ends the same
/// way (server/src/main.cpp). Under ASan the leak check that an exit handler
/// would make is made here; under TSan a report ends the process at once
/// (halt_on_error, as deploy/sanitize.sh runs it).
[[noreturn]] void end_process(int status) {
  std::cout.flush();
  std::cerr.flush();
  std::fflush(nullptr);
#ifdef LIPSYNC_ADDRESS_SANITIZER
  __lsan_do_leak_check();  // ends the process with LSan's exit code if something leaked
#endif
  std::_Exit(status);
}

}  // namespace

int main(int argc, char** argv) { end_process(run(std::vector<std::string_view>(argv + 1, argv + argc))); }
