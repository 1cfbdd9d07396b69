// `lipsync say TEXT`: text in, speech and an animation track out. espeak-ng
// speaks the text (lipsync::speech::synthesize) and reports the phonemes it
// spoke with their sample positions; those timings go through the same render
// path as `lipsync render` (track, --mesh, --video, --still), with the track
// extended to cover the whole audio. --wav keeps the speech; --video muxes it,
// through a temporary WAV next to the video when --wav is not given.
#include <unistd.h>

#include <filesystem>
#include <iostream>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "files.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/synthesizer.hpp"
#include "render_outputs.hpp"
#include "speech_input.hpp"

namespace lipsync::cli {
namespace {

constexpr OptionSpec kOptions[] = {
    kTrackOutputOption,
    kRenderFormatOption,
    kExtendedShapesOption,
    kMohoFpsOption,
    kFpsOrRhubarbCuesOption,
    {"wav", 0, "FILE", "also write the speech to FILE (16-bit mono PCM WAV at espeak-ng's 22050 Hz)", "no WAV"},
    kVoiceOption,
    kRateOption,
    kModelOption,
    kClosureFractionOption,
    kFixedRateOption,
    kIncrementalOption,
    kLookaheadOption,
    kMeshOption,
    kMeshSubdivisionOption,
    kVideoOption,
    kStillOption,
    kStillAtOption,
    kNoBlinksOption,
    kMeshSolveOption,
};

constexpr std::string_view kUsage = "lipsync say TEXT [options]";
constexpr std::string_view kDescription =
    "Speaks TEXT with espeak-ng and renders the phonemes it spoke, timed on its own\n"
    "audio, to an animation track (as 'lipsync render' does), which covers the whole\n"
    "audio. --wav keeps the speech; --video renders the face with the speech as its sound.";

// Deletes a temporary file when it goes out of scope.
struct TemporaryFile {
  std::string path;
  ~TemporaryFile() {
    if (!path.empty()) ::unlink(path.c_str());
  }
};

}  // namespace

int run_say(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "say");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (arguments.positional().empty()) throw UsageError("say needs a TEXT to speak (see 'lipsync say --help')");
  if (arguments.positional().size() > 1) {
    throw UsageError("say takes one TEXT (quote it), got also '" + arguments.positional()[1] + "'");
  }
  const speech::SynthesisOptions synthesis = synthesis_options(arguments);
  const std::optional<std::string> wav_path = arguments.value("wav");
  if (wav_path && (wav_path->empty() || *wav_path == "-")) throw UsageError("--wav: needs a file name");
  OutputRequest request = parse_output_request(arguments);

  speech::Synthesis speech = speech::synthesize(arguments.positional().front(), synthesis);
  for (const std::string& note : speech.notes) std::cerr << "lipsync: warning: " << note << '\n';
  request.audio_end_us = speech.audio.duration_us();
  TemporaryFile temporary;
  if (wav_path) {
    AtomicOutputFile file(*wav_path);
    speech::write_wav(file.stream(), speech.audio);
    file.commit();
    request.audio_path = wav_path;
  } else if (request.video_path) {
    const std::filesystem::path video(*request.video_path);
    temporary.path =
        (video.parent_path() / ("." + video.filename().string() + ".wav.tmp-" + std::to_string(::getpid()))).string();
    AtomicOutputFile file(temporary.path);
    speech::write_wav(file.stream(), speech.audio);
    file.commit();
    request.audio_path = temporary.path;
  }
  render_outputs(request, speech.phonemes);
  return 0;
}

}  // namespace lipsync::cli
