// `lipsync voices`: the espeak-ng voices of this machine, one a line: the name --voice takes (the
// voice file's name), the languages the voice speaks (its own first), and its name. Read from
// espeak-ng-data alone (lipsync::speech::list_voices), so it works where Debian's espeak-ng-data is
// installed without the `espeak-ng` program. lipsyncd's Speak speaks with the voices of its own
// machine: the same list where the same package is installed.
#include <algorithm>
#include <iostream>
#include <string>
#include <vector>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "lipsync/error.hpp"
#include "lipsync/speech/synthesizer.hpp"

namespace lipsync::cli {
namespace {

constexpr std::string_view kUsage = "lipsync voices";
constexpr std::string_view kDescription =
    "Lists the espeak-ng voices of this machine: VOICE, the name --voice takes\n"
    "(lipsync say, speak, align), the languages it speaks (its own first) and its\n"
    "name. A language code or the name works with --voice too; a name that is no\n"
    "voice is refused naming the closest ones.";

}  // namespace

int run_voices(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, {}, "voices");
  if (print_help_if_asked(arguments, kUsage, kDescription, {}, std::cout)) return 0;
  if (!arguments.positional().empty()) {
    throw UsageError("voices takes no arguments, got '" + arguments.positional().front() + "'");
  }
  struct Row {
    std::string voice, languages, name;
  };
  std::vector<Row> rows = {{"VOICE", "LANGUAGES", "NAME"}};
  for (const speech::Voice& voice : speech::list_voices()) {
    Row row{speech::voice_option_name(voice), "", voice.name};
    for (const std::string& language : voice.languages) row.languages += (row.languages.empty() ? "" : ",") + language;
    rows.push_back(std::move(row));
  }
  if (rows.size() == 1) {
    throw InputError("espeak-ng", 0, "no voices here (is espeak-ng-data installed? 'apt-get install espeak-ng-data')");
  }
  std::sort(rows.begin() + 1, rows.end(), [](const Row& a, const Row& b) { return a.voice < b.voice; });
  std::size_t voice_width = 0, languages_width = 0;
  for (const Row& row : rows) {
    voice_width = std::max(voice_width, row.voice.size());
    languages_width = std::max(languages_width, row.languages.size());
  }
  for (const Row& row : rows) {
    std::cout << row.voice << std::string(voice_width - row.voice.size() + 2, ' ') << row.languages
              << std::string(languages_width - row.languages.size() + 2, ' ') << row.name << '\n';
  }
  return 0;
}

}  // namespace lipsync::cli
