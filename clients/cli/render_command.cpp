// `lipsync render INPUT`: a timed phoneme file in, an animation track out.
//
// Every option is checked before any work is done, and the whole track is
// computed before the output file is created, so a bad command line or a bad
// input never leaves a file behind.
#include <iostream>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "files.hpp"
#include "pipeline.hpp"

namespace lipsync::cli {
namespace {

static_assert(RenderOptions{}.fps == 30 && RenderOptions{}.lookahead == 7,
              "update the defaults shown by --help");
static_assert(SegmentOptions{}.closure_fraction == 0.6, "update the default shown by --help");

constexpr OptionSpec kOptions[] = {
    {"output", 'o', "FILE", "write the track to FILE (all or nothing, via a temporary file); - for stdout",
     "stdout"},
    {"format", 0, "FORMAT", "track format: json, csv or arkit-csv (Unreal Live Link Face CSV)", "json"},
    {"fps", 0, "N", "frames per second of the uniform grid, 1 to 240", "30"},
    {"model", 0, "FILE", "articulation model JSON (see 'lipsync model dump')", "the built-in model"},
    {"phone-set", 0, "NAME", "phone set of the labels (see 'lipsync phone-sets'), or auto to detect it",
     "the set the file declares, else auto"},
    {"input-format", 0, "FORMAT", "json, textgrid, timit, lab, pho or flite",
     "detected from the content, then the file extension"},
    {"tier", 0, "NAME", "TextGrid tier that holds the phonemes", "phones"},
    {"sample-rate", 0, "HZ", "sample rate of the sample numbers in a TIMIT .PHN file, > 0", "16000"},
    {"closure-fraction", 0, "F",
     "share of a /p b/ given to its closure when the input has no closure label, in (0, 1)", "0.6"},
    {"fixed-rate", 0, "", "uniform grid only: no key frames at closures and short phonemes", "off"},
    {"incremental", 0, "",
     "feed the phonemes one at a time through the streaming renderer (output identical to offline)", "off"},
    {"lookahead", 0, "N",
     "segments after a frame's own that must be known before it is computed, 0 to 7 (7 is exact)", "7"},
};

constexpr std::string_view kUsage = "lipsync render INPUT [options]";
constexpr std::string_view kDescription =
    "Renders a timed phoneme file (INPUT, or - for standard input) to a coarticulated\n"
    "animation track: one frame per grid step at --fps, plus key frames at the closure\n"
    "and release of /p b m f v/ and in phonemes too short for the grid.";

}  // namespace

int run_render(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "render");
  if (arguments.help()) {
    std::cout << format_help(kUsage, kDescription, kOptions);
    return 0;
  }
  if (arguments.positional().empty()) {
    throw UsageError("render needs an INPUT file (or - for standard input) (see 'lipsync render --help')");
  }
  if (arguments.positional().size() > 1) {
    throw UsageError("render takes one INPUT, got also '" + arguments.positional()[1] + "'");
  }
  const std::string& input = arguments.positional().front();

  const std::string output = arguments.value("output").value_or("-");
  const TrackFormat format = parse_track_format_option(arguments.value("format").value_or("json"));
  std::optional<InputFormat> input_format;
  if (const auto text = arguments.value("input-format")) input_format = parse_input_format_option(*text);

  ParseOptions parse_options;
  if (const auto tier = arguments.value("tier")) {
    if (tier->empty()) throw UsageError("--tier: the tier name must not be empty");
    parse_options.tier = *tier;
  }
  if (const auto rate = arguments.value("sample-rate")) {
    parse_options.timit_sample_rate_hz = parse_int_option("sample-rate", *rate, 1, 100'000'000);
  }

  TrackRequest request;
  if (const auto fps = arguments.value("fps")) request.render.fps = parse_int_option("fps", *fps, 1, 240);
  if (const auto lookahead = arguments.value("lookahead")) {
    request.render.lookahead = parse_int_option("lookahead", *lookahead, 0, 7);
  }
  request.render.fixed_rate = arguments.flag("fixed-rate");
  request.incremental = arguments.flag("incremental");
  if (const auto text = arguments.value("closure-fraction")) {
    const double fraction = parse_double_option("closure-fraction", *text);
    if (!(fraction > 0.0 && fraction < 1.0)) {
      throw UsageError("--closure-fraction: '" + *text + "' is out of range (strictly between 0 and 1)");
    }
    request.segments.closure_fraction = fraction;
  }
  const std::optional<std::string> phone_set_name = arguments.value("phone-set");
  if (phone_set_name && phone_set_name->empty()) throw UsageError("--phone-set: the name must not be empty");

  if (input == "-" && arguments.value("model") == "-") {
    throw UsageError("--model: '-' and INPUT '-' cannot both read standard input");
  }
  const ModelSource model_source(arguments.value("model"));
  const ArticulationModel& model = model_source.model();

  const std::string content = read_file(input);
  const std::string source = input == "-" ? std::string(kStdinName) : input;
  const InputFormat chosen_format = input_format ? *input_format : detect_input_format(source, content);
  const LabeledUtterance utterance = parse_utterance(content, chosen_format, source, parse_options);

  std::vector<PhoneSet> candidates;
  const PhoneSet& phone_set = choose_phone_set(phone_set_name, utterance, model, candidates);
  const Track track = render_utterance(utterance, model, phone_set, request);
  write_output(track, model, format, output);
  return 0;
}

}  // namespace lipsync::cli
