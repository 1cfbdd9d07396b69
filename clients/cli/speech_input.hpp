// Speech as input to the command line: the --text / --text-file options, the
// alignment of a WAV file through lipsync::speech (its notes printed to
// stderr), the length of an --audio WAV, and the --voice / --rate options of
// `say` (spoken here) and `speak` (spoken by lipsyncd).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "arguments.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/synthesizer.hpp"
#include "setting_help.hpp"

namespace lipsync::cli {

inline constexpr OptionSpec kTextOption = {
    "text", 0, "WORDS", "transcript of a WAV INPUT, for forced alignment (phones are recognised without one)", "none"};
inline constexpr OptionSpec kTextFileOption = {"text-file", 0, "FILE", "the transcript read from FILE (UTF-8)", "none"};

inline constexpr OptionSpec kRecordingVoiceOption = {
    "voice", 0, "NAME",
    "language of a WAV INPUT: an espeak-ng voice; the transcript is aligned against espeak-ng's rendering of it in "
    "that voice (dynamic time warping); English voices keep PocketSphinx unless --aligner dtw",
    "English, PocketSphinx"};
inline constexpr OptionSpec kAlignerOption = {
    "aligner", 0, "NAME", "aligner of a WAV INPUT: pocketsphinx (English only) or dtw (needs a transcript)",
    "dtw for a non-English --voice, else pocketsphinx"};

inline constexpr OptionSpec kVoiceOption = {"voice", 0, "NAME", "espeak-ng voice ('lipsync voices' lists them)",
                                            "en-us"};
inline constexpr OptionSpec kRateOption = {
    "rate", 0, "WPM", kRangedHelp<"speaking rate in words per minute", speech::kWordsPerMinuteSetting>.view(),
    kDefaultText<speech::kWordsPerMinuteSetting>.view()};

/// The synthesis options from --voice and --rate (UsageError for an empty voice or a rate out of range).
speech::SynthesisOptions synthesis_options(const Arguments& arguments);

/// The transcript from --text or --text-file (UsageError if both; FileError if unreadable).
std::optional<std::string> transcript_option(const Arguments& arguments);

/// Which aligner a WAV INPUT goes through, from --text/--text-file, --voice and --aligner.
struct RecordingAlignment {
  std::optional<std::string> transcript;
  /// Set: align against espeak-ng's rendering in this voice (DTW). Unset: PocketSphinx.
  std::optional<speech::SynthesisOptions> dtw_voice;
};

/// Reads --text/--text-file, --voice and --aligner: DTW for a non-English voice or with
/// --aligner dtw (voice en-us when none is given), else PocketSphinx. UsageError for an
/// unknown aligner or DTW without a transcript.
RecordingAlignment recording_alignment_options(const Arguments& arguments);

/// Decodes and aligns the WAV bytes `content` of `source`; prints the conversions
/// done on the audio as notes on stderr. Throws InputError.
speech::Alignment align_wav(std::string_view content, const std::string& source, const RecordingAlignment& request);

/// The length of `path` in µs if it is a WAV file, else nullopt. Throws FileError
/// if it cannot be read, InputError if it is a broken WAV.
std::optional<std::int64_t> wav_duration_if_wav(const std::string& path);

}  // namespace lipsync::cli
