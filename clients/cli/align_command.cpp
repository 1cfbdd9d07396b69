// `lipsync align SPEECH.wav`: recorded speech in, a Praat TextGrid of its
// phones (and words, with a transcript) out, which `lipsync render` and other
// tools read. The alignment is lipsync::speech::align_speech (PocketSphinx, English)
// or align_speech_to_synthesis (any espeak-ng voice, dtw_aligner.hpp).
#include <iostream>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "files.hpp"
#include "lipsync/speech/audio.hpp"
#include "speech_input.hpp"

namespace lipsync::cli {
namespace {

constexpr OptionSpec kOptions[] = {
    {"output", 'o', "FILE", "write the TextGrid to FILE (all or nothing, via a temporary file); - for stdout",
     "stdout"},
    kTextOption,
    kTextFileOption,
    kRecordingVoiceOption,
    kAlignerOption,
};

constexpr std::string_view kUsage =
    "lipsync align SPEECH.wav [--text WORDS | --text-file FILE] [--voice NAME] [options]";
constexpr std::string_view kDescription =
    "Aligns recorded speech with PocketSphinx and writes a Praat TextGrid with the tiers\n"
    "'phones' (ARPAbet, empty labels for pauses) and 'words' (the transcript's, or those recognised).\n"
    "With a non-English --voice (or --aligner dtw) the recording is aligned instead against\n"
    "espeak-ng's rendering of the transcript in that voice (MFCC frames, dynamic time\n"
    "warping; docs/languages.md): 'phones' then has espeak-ng's phonemes (IPA), no 'words',\n"
    "and up to 600 s of audio are accepted.\n"
    "With --text or --text-file the words are force-aligned; without, the words\n"
    "PocketSphinx recognises are, where they fit the audio (a note names them), else the\n"
    "phones are recognised one by one (less exact). Either way the starts and ends of /p b m f v/ then\n"
    "move to where the sound shows the lips closing and opening (the steps of its\n"
    "400-3500 Hz level, within 30 ms). The WAV is best 16 kHz mono 16-bit; other rates,\n"
    "channel counts and sample sizes are converted (a note on stderr says so). At most\n"
    "120 s of audio; split longer recordings at pauses.";

}  // namespace

int run_align(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "align");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (arguments.positional().empty()) throw UsageError("align needs a WAV file (see 'lipsync align --help')");
  if (arguments.positional().size() > 1) {
    throw UsageError("align takes one WAV file, got also '" + arguments.positional()[1] + "'");
  }
  const std::string& input = arguments.positional().front();
  const std::string output = arguments.value("output").value_or("-");
  const RecordingAlignment request = recording_alignment_options(arguments);

  const std::string content = read_file(input);
  const std::string source = input == "-" ? std::string(kStdinName) : input;
  const speech::Alignment alignment = align_wav(content, source, request);
  const std::int64_t duration_us = alignment.phones.intervals.back().end_us;
  write_to_output(output, "TextGrid", [&](std::ostream& out) { speech::write_textgrid(out, alignment, duration_us); });
  return 0;
}

}  // namespace lipsync::cli
