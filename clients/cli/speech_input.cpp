#include "speech_input.hpp"

#include <iostream>

#include "cli_error.hpp"
#include "files.hpp"
#include "lipsync/speech/audio.hpp"

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

speech::Alignment align_wav(std::string_view content, const std::string& source,
                            const std::optional<std::string>& transcript) {
  speech::DecodedWav wav = speech::decode_wav(content, source);
  speech::AlignmentOptions options;
  options.transcript = transcript;
  speech::Alignment alignment = speech::align_speech(wav.audio, source, options);
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
