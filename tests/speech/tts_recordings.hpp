// Speech whose phone timings are known: flite's slt voice (`flite -psdur` prints its
// segment ends) and Festival's kal_diphone voice (its segment relation), each WAV
// written to a file and read back with the phones the synthesiser reports. For the
// accuracy tool (tests/bench/alignment_accuracy.cpp) and the alignment tests.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <string>

#include "lipsync/formats.hpp"
#include "lipsync/speech/audio.hpp"

namespace lipsync::testing {

struct Recording {
  speech::PcmAudio audio;
  LabeledUtterance phonemes;  ///< the synthesiser's own ("radio" phone set)
};

/// Runs `command`, returns its standard output and the WAV it wrote to `wav` with
/// phones parsed as `format`; nullopt when it printed nothing.
inline std::optional<Recording> run_recording(const std::string& command, const std::filesystem::path& wav,
                                              InputFormat format, const char* source) {
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(::popen(command.c_str(), "r"), ::pclose);
  if (!pipe) return std::nullopt;
  std::string output;
  char buffer[4096];
  for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, pipe.get())) > 0;) output.append(buffer, n);
  if (output.empty()) return std::nullopt;
  std::ifstream in(wav, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return Recording{speech::decode_wav(bytes, wav.string()).audio, parse_utterance(output, format, source)};
}

/// `text` (no double quotes) spoken by flite's slt voice (16 kHz).
inline std::optional<Recording> flite_recording(const std::string& text, const std::filesystem::path& wav) {
  return run_recording("flite -voice slt -psdur -t \"" + text + "\" -o " + wav.string() + " 2>/dev/null", wav,
                       InputFormat::flite, "flite");
}

/// `text` (no double quotes) spoken by Festival's kal_diphone voice (16 kHz).
inline std::optional<Recording> festival_recording(const std::string& text, const std::filesystem::path& wav) {
  std::string quoted;  // inside the shell's single quotes: ' is written '\''
  for (const char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return run_recording("festival -b '(voice_kal_diphone)' '(set! u (SynthText \"" + quoted +
                           "\"))' '(utt.save.wave u \"" + wav.string() + "\")' '(utt.save.segs u \"-\")' 2>/dev/null",
                       wav, InputFormat::lab, "festival");
}

}  // namespace lipsync::testing
