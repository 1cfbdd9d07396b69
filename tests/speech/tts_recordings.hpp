// Speech whose phone timings are known: flite's slt voice (`flite -psdur` prints its
// segment ends) and Festival's kal_diphone voice (its segment relation), each WAV
// written to a file and read back with the phones the synthesiser reports. For the
// accuracy tool (tests/bench/alignment_accuracy.cpp) and the alignment tests.
//
// espeak-ng's own phoneme events time a stop at its burst: the closure before it,
// which espeak-ng writes as digital silence, is labelled as the end of the previous
// phoneme. A face closes its lips where the sound stops, so for scoring closures
// espeak_stops_from_their_closures moves each /p b/ (and /t d k g/) that follows such
// a silence back to where the silence starts, measured on the samples: the truth of a
// stop's start is then the acoustic closure, as in flite's and Festival's labels.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "lipsync/formats.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/time.hpp"
#include "lipsync/word_marks.hpp"

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

/// The words of `text` as Festival's kal_diphone voice speaks them in festival_recording, each with
/// the start of its first phone (the word marks a TTS gives), µs; empty when Festival is missing.
inline std::vector<TimedWord> festival_word_starts(const std::string& text) {
  std::string quoted;  // inside the shell's single quotes: ' is written '\''
  for (const char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  const std::string command = "festival -b '(voice_kal_diphone)' '(set! u (SynthText \"" + quoted +
                              "\"))' '(mapcar (lambda (w) (format t \"%s %f\\n\" (item.name w) (item.feat w "
                              "\"word_start\"))) (utt.relation.items u (quote Word)))' 2>/dev/null";
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(::popen(command.c_str(), "r"), ::pclose);
  std::vector<TimedWord> words;
  if (!pipe) return words;
  char name[256];
  char seconds[64];
  while (std::fscanf(pipe.get(), "%255s %63s", name, seconds) == 2) {
    words.push_back({name, parse_seconds_to_us(seconds).value_or(0)});
  }
  return words;
}

/// The stops of espeak-ng's phonemes (`espeak` phone set, as synthesize reports them for
/// `audio`) moved to the start of the closure's silence before their burst: the run of
/// samples of at most kClosureSilence in magnitude that ends within 5 ms of the stop's
/// label, when it lasts 10 ms or more and starts after the previous phoneme does. Other
/// phonemes, and stops with no such silence (a /b/ voiced through), keep their label.
inline void espeak_stops_from_their_closures(const speech::PcmAudio& audio, LabeledUtterance& phonemes) {
  constexpr int kClosureSilence = 32;  // -60 dBFS: espeak-ng writes closures as zeros
  const auto sample_at = [&](std::int64_t us) { return us * audio.sample_rate_hz / 1'000'000; };
  const auto is_stop = [](const std::string& label) {
    return label == "p" || label == "b" || label == "t" || label == "d" || label == "k" || label == "g";
  };
  for (std::size_t i = 1; i < phonemes.intervals.size(); ++i) {
    LabeledInterval& stop = phonemes.intervals[i];
    LabeledInterval& previous = phonemes.intervals[i - 1];
    if (!is_stop(stop.label)) continue;
    const auto quiet = [&](std::int64_t k) {
      return k >= 0 && k < static_cast<std::int64_t>(audio.samples.size()) &&
             std::abs(int(audio.samples[static_cast<std::size_t>(k)])) <= kClosureSilence;
    };
    std::int64_t end = sample_at(stop.start_us);
    const std::int64_t earliest_end = end - sample_at(5'000);
    while (end > earliest_end && !quiet(end - 1)) --end;  // the burst may start a little before the label
    std::int64_t begin = end;
    while (begin > 0 && quiet(begin - 1)) --begin;
    const std::int64_t begin_us = begin * 1'000'000 / audio.sample_rate_hz;
    if (end - begin < sample_at(10'000) || begin_us <= previous.start_us) continue;
    previous.end_us = stop.start_us = begin_us;
  }
}

}  // namespace lipsync::testing
