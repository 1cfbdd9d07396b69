// alignment_accuracy: how close lipsync::speech's PocketSphinx alignment comes to
// phoneme boundaries that are known exactly, on synthetic speech.
//
// Each sentence (ten Harvard sentences by default, public domain) is spoken by espeak-ng
// through lipsync::speech::synthesize, whose phoneme events give the true
// boundaries (its stops moved from their bursts back to the start of their closures'
// silence, tests/speech/tts_recordings.hpp), and, when flite is on PATH, by flite's slt voice (`flite -psdur`
// prints its segment ends; its audio is 16 kHz already), and, when festival is
// on PATH, by Festival's kal_diphone voice (its segment relation gives the
// boundaries; 16 kHz). Each recording is aligned twice: with its transcript
// (forced alignment) and without (phone recognition); each alignment is scored
// as the recogniser left it ("raw") and after refine_closures moved its lip
// boundaries to the signal ("refined"), in the same run on the same decode.
// Boundaries are scored as tests/speech/boundary_errors.hpp describes; the tool
// prints, per source and mode, the median and 95th percentile boundary error in
// ms, the share of reference phonemes matched, the share of bilabial closures
// found within 20 ms, their median and 95th percentile start error, and the
// share shown closed at their middle. docs/input-formats.md ("Speech in") quotes
// its output.
//
// Usage: alignment_accuracy [--espeak-only]
// ALIGNMENT_ACCURACY_SENTENCES chooses the sentences: unset, the first ten (what the
// refiner was first tuned on); "next", Harvard sentences 11 to 20 (a check on sentences
// the first rules were not tuned on; later rules were chosen on them); "third", sentences
// 21 to 30 (Harvard list 3); "FROM-TO", the 1-based inclusive range of Harvard sentence
// numbers within tests/support/harvard_sentences.hpp (1 to 50), e.g. "31-50" (lists 4 and 5)
// or "21-50". No rule or setting was tuned on sentences 21 to 50: they are the fresh check.
// Any other value (a range out of bounds or with FROM > TO included) is an error (exit 2).
// With ALIGNMENT_ACCURACY_DUMP=DIR it also writes each recording (16 kHz WAV), its
// reference phones and the raw alignment (label, start µs, end µs per line) to DIR,
// for trying refiner settings without decoding again.
#include <unistd.h>

#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>

#include "../speech/boundary_errors.hpp"
#include "../speech/tts_recordings.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/synthesizer.hpp"

namespace {

using namespace lipsync;
using testing::festival_recording;
using testing::flite_recording;
using testing::Recording;

void report(const std::string& name, const testing::BoundaryScore& score, double seconds_audio, double seconds_cpu) {
  std::printf(
      "%-30s boundaries %4zu  median %5.1f ms  p95 %6.1f ms  (signed median %+5.1f ms)  matched %5.1f %%  bilabials "
      "%2d/%2d within 20 ms (%5.1f %%, median %5.1f ms, p95 %5.1f ms)  closed at middle %2d/%2d (%5.1f %%)  false "
      "closures "
      "%2d/%3d  %.2fx real time\n",
      name.c_str(), score.errors_ms.size(), testing::quantile(score.errors_ms, 0.5),
      testing::quantile(score.errors_ms, 0.95), testing::quantile(score.signed_errors_ms, 0.5),
      100.0 * score.matched_phonemes / std::max(1, score.reference_phonemes), score.bilabials_within_20ms,
      score.bilabials, 100.0 * score.bilabials_within_20ms / std::max(1, score.bilabials),
      testing::quantile(score.bilabial_errors_ms, 0.5), testing::quantile(score.bilabial_errors_ms, 0.95),
      score.bilabials_closed_at_middle, score.bilabials,
      100.0 * score.bilabials_closed_at_middle / std::max(1, score.bilabials), score.false_closures,
      score.other_phonemes, seconds_cpu / seconds_audio);
}

// "FROM-TO", 1-based and inclusive, within 1..count; nullopt for anything else.
std::optional<std::pair<std::size_t, std::size_t>> sentence_range(std::string_view value, std::size_t count) {
  const std::size_t dash = value.find('-');
  if (dash == std::string_view::npos) return std::nullopt;
  const auto number = [](std::string_view digits) -> std::optional<std::size_t> {
    std::size_t n = 0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), n);
    if (digits.empty() || error != std::errc() || end != digits.data() + digits.size()) return std::nullopt;
    return n;
  };
  const std::optional<std::size_t> from = number(value.substr(0, dash)), to = number(value.substr(dash + 1));
  if (!from || !to || *from < 1 || *from > *to || *to > count) return std::nullopt;
  return std::pair(*from, *to);
}

}  // namespace

int main(int argc, char** argv) {
  const bool espeak_only = argc > 1 && std::string_view(argv[1]) == "--espeak-only";
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  const bool have_flite = !espeak_only && std::system("command -v flite >/dev/null 2>&1") == 0;
  const bool have_festival = !espeak_only && std::system("command -v festival >/dev/null 2>&1") == 0;
  const std::filesystem::path wav =
      std::filesystem::temp_directory_path() / ("alignment_accuracy-" + std::to_string(::getpid()) + ".wav");

  std::span<const char* const> sentences = testing::accuracy_sentences();
  if (const char* which = std::getenv("ALIGNMENT_ACCURACY_SENTENCES")) {
    const std::string_view value(which);
    const std::span<const char* const> all(testing::kHarvardSentences);
    if (value == "next") {
      sentences = all.subspan(10, 10);
    } else if (value == "third") {
      sentences = all.subspan(20, 10);
    } else if (const std::optional<std::pair<std::size_t, std::size_t>> range = sentence_range(value, all.size())) {
      sentences = all.subspan(range->first - 1, range->second - range->first + 1);
    } else {
      std::cerr << "alignment_accuracy: ALIGNMENT_ACCURACY_SENTENCES=\"" << value
                << "\" is not known; use \"next\" (sentences 11 to 20), \"third\" (21 to 30), a range FROM-TO of "
                   "Harvard sentence numbers with 1 <= FROM <= TO <= "
                << all.size() << " (e.g. \"31-50\"), or leave it unset (the first ten)\n";
      return 2;
    }
  }

  for (const std::string source : {"espeak-ng", "flite", "festival"}) {
    if (source == "flite" && !have_flite) continue;
    if (source == "festival" && !have_festival) continue;
    const PhoneSet reference_set = *PhoneSet::builtin(source == "espeak-ng" ? "espeak" : "radio", model);
    // [with transcript?][refined?]
    testing::BoundaryScore scores[2][2];
    double audio_s = 0, seconds[2] = {0, 0};
    int n = 0;
    for (const char* sentence : sentences) {
      ++n;
      std::optional<Recording> recording;
      if (source == "flite") {
        recording = flite_recording(sentence, wav);
      } else if (source == "festival") {
        recording = festival_recording(sentence, wav);
      } else {
        speech::Synthesis synthesis = speech::synthesize(sentence);
        recording = Recording{std::move(synthesis.audio), std::move(synthesis.phonemes)};
        testing::espeak_stops_from_their_closures(recording->audio, recording->phonemes);
      }
      if (!recording) continue;
      audio_s += double(recording->audio.duration_us()) / 1e6;
      const speech::PcmAudio at_16k = speech::resample(recording->audio, 16000);
      for (const int with_text : {1, 0}) {
        speech::AlignmentOptions options;
        if (with_text) options.transcript = sentence;
        options.refine_closures = false;
        const auto start = std::chrono::steady_clock::now();
        speech::Alignment aligned = speech::align_speech(recording->audio, source, options);
        seconds[with_text] += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        testing::score_alignment(recording->phonemes, reference_set, aligned.phones, arpabet, model,
                                 scores[with_text][0]);
        if (const char* dump = std::getenv("ALIGNMENT_ACCURACY_DUMP")) {  // for tuning the refiner offline
          const std::string stem =
              std::string(dump) + "/" + source + "-" + std::to_string(n) + (with_text ? "-text" : "-free");
          std::ofstream wav_out(stem + ".wav", std::ios::binary);
          speech::write_wav(wav_out, at_16k);
          std::ofstream ref(stem + ".ref"), raw(stem + ".raw");
          for (const auto& i : recording->phonemes.intervals)
            ref << i.label << '\t' << i.start_us << '\t' << i.end_us << '\n';
          for (const auto& i : aligned.phones.intervals)
            raw << i.label << '\t' << i.start_us << '\t' << i.end_us << '\n';
        }
        speech::refine_closures(at_16k, aligned.phones);
        testing::score_alignment(recording->phonemes, reference_set, aligned.phones, arpabet, model,
                                 scores[with_text][1]);
      }
    }
    report(source + " with text, raw", scores[1][0], audio_s, seconds[1]);
    report(source + " with text, refined", scores[1][1], audio_s, seconds[1]);
    report(source + " without, raw", scores[0][0], audio_s, seconds[0]);
    report(source + " without, refined", scores[0][1], audio_s, seconds[0]);
  }
  std::filesystem::remove(wav);
  return 0;
}
