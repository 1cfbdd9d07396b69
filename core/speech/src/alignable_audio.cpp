#include "alignable_audio.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "lipsync/error.hpp"

namespace lipsync::speech::detail {
namespace {

// Audio whose loudest 20 ms stays below this level holds no speech to align.
constexpr double kSilenceDbfs = -50.0;

}  // namespace

std::vector<double> window_levels_dbfs(const PcmAudio& audio) {
  const std::size_t window = std::max<std::size_t>(1, static_cast<std::size_t>(audio.sample_rate_hz / 50));
  std::vector<double> levels;
  levels.reserve(audio.samples.size() / window + 1);
  for (std::size_t start = 0; start < audio.samples.size(); start += window) {
    const std::size_t end = std::min(audio.samples.size(), start + window);
    double energy = 0;
    for (std::size_t i = start; i < end; ++i) energy += double(audio.samples[i]) * audio.samples[i];
    energy /= double(end - start);
    levels.push_back(energy > 0 ? 10 * std::log10(energy / (32768.0 * 32768.0)) : -200.0);
  }
  return levels;
}

std::vector<double> check_alignable_audio(const PcmAudio& audio, const std::string& source, double max_duration_s,
                                          std::string_view purpose) {
  const double duration_s = double(audio.samples.size()) / audio.sample_rate_hz;
  char text[160];
  if (duration_s > max_duration_s) {
    std::snprintf(text, sizeof text,
                  "%.1f s of audio is longer than the %.0f s an alignment accepts; split it at pauses", duration_s,
                  max_duration_s);
    throw InputError(source, 0, text);
  }
  if (audio.sample_rate_hz < 8000) {
    throw InputError(source, 0,
                     "sample rate " + std::to_string(audio.sample_rate_hz) + " Hz is too low for " +
                         std::string(purpose) + " (16000 Hz wanted, 8000 Hz at least)");
  }
  if (duration_s < 0.1) throw InputError(source, 0, "the audio is too short to align (under 0.1 s)");
  std::vector<double> levels = window_levels_dbfs(audio);
  const double loudest = *std::max_element(levels.begin(), levels.end());
  if (loudest < kSilenceDbfs) {
    std::snprintf(text, sizeof text, "no speech found: the audio is silent (its loudest 20 ms is at %.0f dBFS)",
                  loudest);
    throw InputError(source, 0, text);
  }
  return levels;
}

}  // namespace lipsync::speech::detail
