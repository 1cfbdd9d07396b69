#include "speech_input.hpp"

#include <iostream>

#include "cli_error.hpp"
#include "files.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/dtw_aligner.hpp"

namespace lipsync::cli {

speech::SynthesisOptions synthesis_options(const Arguments& arguments) {
  speech::SynthesisOptions options;
  if (const auto voice = arguments.value("voice")) {
    if (voice->empty()) throw UsageError("--voice: the name must not be empty");
    options.voice = *voice;
  }
  options.words_per_minute = parse_setting_option(arguments, "rate", speech::kWordsPerMinuteSetting);
  return options;
}

std::optional<std::string> transcript_option(const Arguments& arguments) {
  auto text = arguments.value("text");
  const auto file = arguments.value("text-file");
  if (text && file) throw UsageError("--text and --text-file cannot both be given");
  if (file) {
    if (file->empty()) throw UsageError("--text-file: needs a file name");
    return read_file(*file);
  }
  return text;
}

RecordingAlignment recording_alignment_options(const Arguments& arguments) {
  RecordingAlignment request;
  request.transcript = transcript_option(arguments);
  const std::optional<std::string> voice = arguments.value("voice");
  if (voice && voice->empty()) throw UsageError("--voice: the name must not be empty");
  const std::string aligner = arguments.value("aligner").value_or(
      voice && speech::phone_set_for_voice(*voice) != "espeak" ? "dtw" : "pocketsphinx");
  if (aligner != "dtw" && aligner != "pocketsphinx") {
    throw UsageError("--aligner: '" + aligner + "' is not an aligner (pocketsphinx or dtw)");
  }
  if (aligner == "pocketsphinx" && voice && speech::phone_set_for_voice(*voice) != "espeak") {
    throw UsageError("--aligner pocketsphinx knows English only, and --voice '" + *voice +
                     "' is not an English voice (use --aligner dtw)");
  }
  if (aligner == "dtw") {
    if (!request.transcript) throw UsageError("--voice / --aligner dtw needs the transcript (--text or --text-file)");
    speech::SynthesisOptions synthesis;
    if (voice) synthesis.voice = *voice;
    request.dtw_voice = synthesis;
  }
  return request;
}

speech::Alignment align_wav(std::string_view content, const std::string& source, const RecordingAlignment& request) {
  speech::DecodedWav wav = speech::decode_wav(content, source);
  speech::Alignment alignment;
  if (request.dtw_voice) {
    speech::DtwAlignmentOptions options;
    options.transcript = *request.transcript;
    options.synthesis = *request.dtw_voice;
    alignment = speech::align_speech_to_synthesis(wav.audio, source, options);
  } else {
    speech::AlignmentOptions options;
    options.transcript = request.transcript;
    alignment = speech::align_speech(wav.audio, source, options);
  }
  wav.notes.insert(wav.notes.end(), alignment.notes.begin(), alignment.notes.end());
  for (const std::string& note : wav.notes) std::cerr << "lipsync: note: " << source << ": " << note << '\n';
  return alignment;
}

std::optional<std::int64_t> wav_duration_if_wav(const std::string& path) {
  const std::string content = read_file(path);
  if (!speech::looks_like_wav(content)) return std::nullopt;
  return speech::wav_layout_and_duration_us(content, path).second;
}

}  // namespace lipsync::cli
