// `lipsync demo`: renders a built-in utterance, so that a fresh build shows
// what lipsyncd does without any input file.
//
// The utterance is "speech synchronization" as timed by flite 2.2
// (`flite -voice slt -psdur -t "speech synchronization" -o none`), converted
// to lipsync utterance JSON in Festival's "radio" phones. It has the cases the
// key-frame rules are about: a /p/ with no separate closure label, short
// phonemes (/r/ 42 ms, /ax/ 37 ms) and /sh ch/ rounding.
#include <filesystem>
#include <iostream>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "lipsync/time.hpp"
#include "pipeline.hpp"

namespace lipsync::cli {
namespace {

constexpr std::string_view kDemoUtterance = R"({
  "text": "speech synchronization",
  "origin": "flite 2.2 -voice slt -psdur -t \"speech synchronization\" -o none",
  "phone_set": "radio",
  "phonemes": [
    {"label": "pau", "start": 0, "end": 0.171},
    {"label": "s", "start": 0.171, "end": 0.287},
    {"label": "p", "start": 0.287, "end": 0.352},
    {"label": "iy", "start": 0.352, "end": 0.447},
    {"label": "ch", "start": 0.447, "end": 0.599},
    {"label": "s", "start": 0.599, "end": 0.701},
    {"label": "ih", "start": 0.701, "end": 0.781},
    {"label": "ng", "start": 0.781, "end": 0.873},
    {"label": "k", "start": 0.873, "end": 0.935},
    {"label": "r", "start": 0.935, "end": 0.977},
    {"label": "ax", "start": 0.977, "end": 1.014},
    {"label": "n", "start": 1.014, "end": 1.060},
    {"label": "ax", "start": 1.060, "end": 1.122},
    {"label": "z", "start": 1.122, "end": 1.206},
    {"label": "ey", "start": 1.206, "end": 1.381},
    {"label": "sh", "start": 1.381, "end": 1.515},
    {"label": "ax", "start": 1.515, "end": 1.620},
    {"label": "n", "start": 1.620, "end": 1.775},
    {"label": "pau", "start": 1.775, "end": 1.960}
  ]
}
)";

constexpr OptionSpec kOptions[] = {
    {"output", 'o', "FILE", "where to write the track; - for stdout",
     "lipsync-demo.json, .csv or .arkit.csv by --format"},
    kTrackFormatOption,
    kFpsOption,
};

constexpr std::string_view kUsage = "lipsync demo [options]";
constexpr std::string_view kDescription =
    "Renders the built-in utterance \"speech synchronization\" (timed by flite) with the\n"
    "built-in model, writes the track and prints where it went.";

std::string default_output(TrackFormat format) {
  switch (format) {
    case TrackFormat::json:
      return "lipsync-demo.json";
    case TrackFormat::csv:
      return "lipsync-demo.csv";
    case TrackFormat::arkit_csv:
      return "lipsync-demo.arkit.csv";
  }
  return "lipsync-demo";
}

}  // namespace

int run_demo(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "demo");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (!arguments.positional().empty()) {
    throw UsageError("demo takes no arguments, got '" + arguments.positional().front() + "'");
  }
  const TrackFormat format = parse_track_format_option(arguments.value("format").value_or("json"));
  TrackRequest request;
  request.render = parse_render_plan(arguments).render;
  const std::string output = arguments.value("output").value_or(default_output(format));

  const ArticulationModel& model = ArticulationModel::builtin();
  const LabeledUtterance utterance = parse_utterance(kDemoUtterance, InputFormat::json, "built-in demo");
  std::vector<PhoneSet> candidates;
  const PhoneSet& phone_set = choose_phone_set(std::nullopt, utterance, model, candidates);
  const Track track = render_utterance(utterance, model, phone_set, request);
  write_output(track, model, format, output);

  const std::string where =
      output == "-" ? std::string("standard output") : std::filesystem::absolute(output).lexically_normal().string();
  const std::int64_t duration_us = utterance.intervals.back().end_us;
  (output == "-" ? std::cerr : std::cout)
      << "lipsync demo: wrote " << track.frame_count() << " frames (" << format_seconds(duration_us) << " s at "
      << track.fps << " fps, " << to_string(format) << ") to " << where << "\n";
  return 0;
}

}  // namespace lipsync::cli
