// lipsync: the command-line client of lipsyncd. Dispatches to a subcommand
// and turns every failure into one line on stderr and an exit status:
// 0 success, 1 bad input or a file problem, 2 a mistake on the command line.
#include <iostream>
#include <string>
#include <string_view>
#include <vector>

#include "cli_error.hpp"
#include "command_main.hpp"
#include "commands.hpp"

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
    {"voices", "list espeak-ng's voices: the name --voice takes, languages, name", run_voices},
#ifdef LIPSYNC_WITH_NETWORK
    {"stream", "stream a phoneme file to lipsyncd and write the frames it sends", run_stream},
    {"speak", "have lipsyncd speak a text (Speak) and write the track (and --wav the speech)", run_speak},
    {"listen", "send speech (a WAV, or a microphone on stdin) to lipsyncd (Listen) and write the frames", run_listen},
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

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string_view> args(argv + 1, argv + argc);
  end_process(report_failures([&] { return dispatch(args); }));
}
