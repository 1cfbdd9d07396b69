// alignment_accuracy: how close lipsync::speech's PocketSphinx alignment comes to
// phoneme boundaries that are known exactly, on synthetic speech.
//
// Each sentence (ten Harvard sentences, public domain) is spoken by espeak-ng
// through lipsync::speech::synthesize, whose phoneme events give the true
// boundaries, and, when flite is on PATH, by flite's slt voice (`flite -psdur`
// prints its segment ends; its audio is 16 kHz already). Each recording is
// aligned twice: with its transcript (forced alignment) and without (phone
// recognition). Boundaries are scored as tests/speech/boundary_errors.hpp
// describes; the tool prints, per source and mode, the median and 95th
// percentile boundary error in ms, the share of reference phonemes matched,
// and the share of bilabial closures found within 20 ms. docs/input-formats.md
// ("Speech in") quotes its output.
//
// Usage: alignment_accuracy [--espeak-only]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <string_view>
#include <unistd.h>

#include "../speech/boundary_errors.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/synthesizer.hpp"

namespace {

using namespace lipsync;


struct Recording {
  speech::PcmAudio audio;
  LabeledUtterance phonemes;
};

std::optional<Recording> flite_recording(const std::string& text, const std::filesystem::path& wav) {
  const std::string command = "flite -voice slt -psdur -t \"" + text + "\" -o " + wav.string() + " 2>/dev/null";
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(::popen(command.c_str(), "r"), ::pclose);
  if (!pipe) return std::nullopt;
  std::string output;
  char buffer[4096];
  for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, pipe.get())) > 0;) output.append(buffer, n);
  if (output.empty()) return std::nullopt;
  std::ifstream in(wav, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return Recording{speech::decode_wav(bytes, wav.string()).audio, parse_utterance(output, InputFormat::flite, "flite")};
}

void report(const std::string& name, const testing::BoundaryScore& score, double seconds_audio, double seconds_cpu) {
  std::printf("%-22s boundaries %4zu  median %5.1f ms  p95 %6.1f ms  (signed median %+5.1f ms)  matched %5.1f %%  bilabials %2d/%2d within 20 ms (%5.1f %%)  %.2fx real time\n",
              name.c_str(), score.errors_ms.size(), testing::quantile(score.errors_ms, 0.5),
              testing::quantile(score.errors_ms, 0.95),
              testing::quantile(score.signed_errors_ms, 0.5), 100.0 * score.matched_phonemes / std::max(1, score.reference_phonemes),
              score.bilabials_within_20ms, score.bilabials, 100.0 * score.bilabials_within_20ms / std::max(1, score.bilabials),
              seconds_cpu / seconds_audio);
}

}  // namespace

int main(int argc, char** argv) {
  const bool espeak_only = argc > 1 && std::string_view(argv[1]) == "--espeak-only";
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  const bool have_flite = !espeak_only && std::system("command -v flite >/dev/null 2>&1") == 0;
  const std::filesystem::path wav = std::filesystem::temp_directory_path() / ("alignment_accuracy-" + std::to_string(::getpid()) + ".wav");

  for (const std::string source : {"espeak-ng", "flite"}) {
    if (source == "flite" && !have_flite) continue;
    const PhoneSet reference_set = *PhoneSet::builtin(source == "flite" ? "radio" : "espeak", model);
    testing::BoundaryScore forced, recognised;
    double audio_s = 0, forced_s = 0, recognised_s = 0;
    for (const char* sentence : testing::accuracy_sentences()) {
      std::optional<Recording> recording;
      if (source == "flite") {
        recording = flite_recording(sentence, wav);
      } else {
        speech::Synthesis synthesis = speech::synthesize(sentence);
        recording = Recording{std::move(synthesis.audio), std::move(synthesis.phonemes)};
      }
      if (!recording) continue;
      audio_s += double(recording->audio.duration_us()) / 1e6;
      speech::AlignmentOptions options;
      options.transcript = sentence;
      auto start = std::chrono::steady_clock::now();
      const speech::Alignment aligned = speech::align_speech(recording->audio, source, options);
      forced_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      testing::score_alignment(recording->phonemes, reference_set, aligned.phones, arpabet, model, forced);
      start = std::chrono::steady_clock::now();
      const speech::Alignment free = speech::align_speech(recording->audio, source, {});
      recognised_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      testing::score_alignment(recording->phonemes, reference_set, free.phones, arpabet, model, recognised);
    }
    report(source + " with text", forced, audio_s, forced_s);
    report(source + " without", recognised, audio_s, recognised_s);
  }
  std::filesystem::remove(wav);
  return 0;
}
