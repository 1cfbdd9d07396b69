// refine_dumped_alignments: the closure refiner tried again on the recordings and raw
// alignments alignment_accuracy wrote with ALIGNMENT_ACCURACY_DUMP=DIR, without
// decoding again (seconds instead of minutes), printing every reference /p b m/ with
// where the truth, the recogniser and the refiner put its start, so that each miss
// can be looked at.
//
// Usage: refine_dumped_alignments DIR [--misses] [--min-step-db=D] [--lead-us=N] [--search-us=N]
//        refine_dumped_alignments --levels WAV FROM_MS TO_MS   (the 1 ms levels and 10 ms falls)
// For each source (espeak-ng, flite, festival) and mode (-text, -free) it prints the
// refined bilabials within 20 ms, their median and p95, and the count shown closed at
// the middle, scored as tests/speech/boundary_errors.hpp does (espeak-ng's references as
// dumped, their stops already moved to their closures on the synthesiser's 22 050 Hz samples:
// tests/speech/tts_recordings.hpp; measured again on the dumped 16 kHz copy, espeak-ng's /p/ of
// "helps" moved where the bench's had not, and the counts differed). With
// --misses it also prints each bilabial the refined alignment starts more than 20 ms
// away from the truth, or does not show closed at its middle. Recordings are numbered
// from 1 within the sentences the bench spoke (ALIGNMENT_ACCURACY_SENTENCES=31-50: "-3-" is
// sentence 33); it reads every number the bench can write, up to the 50 Harvard sentences.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <string_view>

#include "../speech/boundary_errors.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/closure_refiner.hpp"

namespace {

using namespace lipsync;

LabeledUtterance read_phones(const std::filesystem::path& path, const std::string& phone_set) {
  LabeledUtterance utterance;
  utterance.phone_set = phone_set;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    LabeledInterval interval;
    if (line.starts_with('\t')) {
      fields >> interval.start_us >> interval.end_us;  // a silence: no label
    } else {
      fields >> interval.label >> interval.start_us >> interval.end_us;
    }
    utterance.intervals.push_back(interval);
  }
  return utterance;
}

const LabeledInterval* at_time(const LabeledUtterance& u, std::int64_t t) {
  for (const LabeledInterval& i : u.intervals)
    if (i.start_us <= t && t < i.end_us) return &i;
  return nullptr;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: refine_dumped_alignments DIR [--misses]\n");
    return 2;
  }
  if (argc == 5 && std::string_view(argv[1]) == "--levels") {  // WAV FROM_MS TO_MS: 1 ms levels, 10 ms steps
    std::ifstream wav_in(argv[2], std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(wav_in)), std::istreambuf_iterator<char>());
    const speech::PcmAudio audio = speech::decode_wav(bytes, argv[2]).audio;
    const std::vector<double> levels = speech::formant_band_levels_db(audio, 1000, 1000);
    const auto mean = [&](long a, long b) {
      double sum = 0;
      for (long k = a; k < b; ++k) sum += std::max(levels[static_cast<std::size_t>(k)], -70.0);
      return sum / double(b - a);
    };
    for (long k = std::atol(argv[3]); k < std::atol(argv[4]); ++k)
      std::printf("%ld ms  level %6.1f  fall %6.1f\n", k, levels[static_cast<std::size_t>(k)],
                  mean(k - 10, k) - mean(k, k + 10));
    return 0;
  }
  const std::filesystem::path dir = argv[1];
  bool misses = false;
  speech::ClosureRefinerOptions options;
  for (int a = 2; a < argc; ++a) {  // --misses, --min-step-db=D, --lead-us=N, --search-us=N
    const std::string_view arg = argv[a];
    const auto value = [&] { return std::atof(std::string(arg.substr(arg.find('=') + 1)).c_str()); };
    if (arg == "--misses") misses = true;
    if (arg.starts_with("--min-step-db=")) options.min_step_db = value();
    if (arg.starts_with("--lead-us=")) options.closure_lead_us = static_cast<std::int64_t>(value());
    if (arg.starts_with("--search-us=")) options.search_us = static_cast<std::int64_t>(value());
  }
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  for (const std::string source : {"espeak-ng", "flite", "festival"}) {
    const bool espeak = source == "espeak-ng";
    const PhoneSet reference_set = *PhoneSet::builtin(espeak ? "espeak" : "radio", model);
    for (const std::string mode : {"text", "free"}) {
      testing::BoundaryScore raw_score, score;
      for (std::size_t n = 1; n <= testing::kHarvardSentences.size(); ++n) {  // as many as the bench can dump
        const std::string stem = (dir / (source + "-" + std::to_string(n) + "-" + mode)).string();
        std::ifstream wav_in(stem + ".wav", std::ios::binary);
        if (!wav_in) continue;
        const std::string bytes((std::istreambuf_iterator<char>(wav_in)), std::istreambuf_iterator<char>());
        const speech::PcmAudio audio = speech::decode_wav(bytes, stem + ".wav").audio;
        LabeledUtterance reference = read_phones(stem + ".ref", espeak ? "espeak" : "radio");
        const LabeledUtterance raw = read_phones(stem + ".raw", "arpabet");
        LabeledUtterance refined = raw;
        const auto boundaries = speech::refine_closures(audio, refined, options);
        testing::score_alignment(reference, reference_set, raw, arpabet, model, raw_score);
        testing::score_alignment(reference, reference_set, refined, arpabet, model, score);
        if (!misses) continue;
        for (const LabeledInterval& r : reference.intervals) {
          const auto phoneme = reference_set.lookup(r.label);
          if (!phoneme) continue;
          const std::string& name = model.phonemes()[*phoneme].name;
          if (name != "p" && name != "b" && name != "m") continue;
          const std::int64_t middle = (r.start_us + r.end_us) / 2;
          const LabeledInterval* shown = at_time(refined, middle);
          // the nearest refined phone of the same name
          const LabeledInterval* same = nullptr;
          for (const LabeledInterval& a : refined.intervals) {
            const auto p = arpabet.lookup(a.label);
            if (p && *p == *phoneme &&
                (!same || std::llabs(a.start_us - r.start_us) < std::llabs(same->start_us - r.start_us)))
              same = &a;
          }
          const LabeledInterval* raw_same = nullptr;
          for (const LabeledInterval& a : raw.intervals) {
            const auto p = arpabet.lookup(a.label);
            if (p && *p == *phoneme &&
                (!raw_same || std::llabs(a.start_us - r.start_us) < std::llabs(raw_same->start_us - r.start_us)))
              raw_same = &a;
          }
          const double error_ms = same ? double(same->start_us - r.start_us) / 1000 : 1e9;
          const bool closed = shown && arpabet.lookup(shown->label) &&
                              (model.phonemes()[*arpabet.lookup(shown->label)].name == "p" ||
                               model.phonemes()[*arpabet.lookup(shown->label)].name == "b" ||
                               model.phonemes()[*arpabet.lookup(shown->label)].name == "m");
          if (std::abs(error_ms) <= 20 && closed) continue;
          double step = 0;
          for (const auto& b : boundaries)
            if (same && !b.release && &refined.intervals[b.phone] == same) step = b.step_db;
          std::printf(
              "  %s-%zu-%s /%s/ truth %.3f-%.3f  raw %s %.3f  refined %.3f (%+.1f ms, step %.1f dB)  middle shows "
              "'%s'\n",
              source.c_str(), n, mode.c_str(), name.c_str(), double(r.start_us) / 1e6, double(r.end_us) / 1e6,
              raw_same ? raw_same->label.c_str() : "-", raw_same ? double(raw_same->start_us) / 1e6 : 0.0,
              same ? double(same->start_us) / 1e6 : 0.0, error_ms, step, shown ? shown->label.c_str() : "?");
        }
      }
      std::printf(
          "%-10s %-4s raw %2d/%2d  refined %2d/%2d within 20 ms (median %5.1f ms, p95 %5.1f ms)  closed at middle "
          "%2d/%2d  false closures %2d/%3d  boundaries median %5.1f p95 %5.1f\n",
          source.c_str(), mode.c_str(), raw_score.bilabials_within_20ms, raw_score.bilabials,
          score.bilabials_within_20ms, score.bilabials, testing::quantile(score.bilabial_errors_ms, 0.5),
          testing::quantile(score.bilabial_errors_ms, 0.95), score.bilabials_closed_at_middle, score.bilabials,
          score.false_closures, score.other_phonemes, testing::quantile(score.errors_ms, 0.5),
          testing::quantile(score.errors_ms, 0.95));
    }
  }
  return 0;
}
