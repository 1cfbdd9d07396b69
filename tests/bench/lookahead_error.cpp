// What a smaller lookahead costs: renders real utterances (flite's timing for
// the first 20 Harvard sentences, lists 1 and 2, which docs/streaming.md's figures
// were measured on) at every lookahead 0–7 and compares each with the exact render
// (lookahead 7), channel by channel. Prints a Markdown table for docs/streaming.md.
//
//   build/tests/bench/lookahead_error [--fps N]
// Needs /usr/bin/flite (Debian package flite).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <span>
#include <string>

#include "../support/harvard_sentences.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"

namespace {

std::string flite_timing(const std::string& sentence) {
  const std::string command = "flite -voice slt -psdur -o none -t \"" + sentence + "\"";
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
  if (!pipe) throw std::runtime_error("cannot run flite");
  std::string output;
  std::array<char, 4096> buffer{};
  while (std::size_t n = std::fread(buffer.data(), 1, buffer.size(), pipe.get())) output.append(buffer.data(), n);
  return output;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace lipsync;
  int fps = 30;
  if (argc == 3 && std::string(argv[1]) == "--fps") fps = std::stoi(argv[2]);
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet radio = *PhoneSet::builtin("radio", model);

  std::vector<std::vector<Segment>> utterances;
  for (const char* sentence : std::span(lipsync::testing::kHarvardSentences).first(20)) {
    const LabeledUtterance parsed = parse_utterance(flite_timing(sentence), InputFormat::flite, "flite");
    utterances.push_back(build_segments(parsed, model, radio));
  }
  std::size_t jaw = 0;
  for (std::size_t c = 0; c < model.channel_count(); ++c) {
    if (model.channels()[c].name == "jaw_rotation") jaw = c;
  }

  std::cout << "| lookahead | mean wait (ms) | p95 wait (ms) | max wait (ms) | RMS error, all channels | max error, "
               "all channels | "
               "max error, jaw_rotation | frames off by > 0.01 |\n|---|---|---|---|---|---|---|---|\n";
  for (int lookahead = 0; lookahead <= 7; ++lookahead) {
    double squared = 0.0;
    double worst = 0.0;
    double worst_jaw = 0.0;
    std::size_t values = 0;
    std::size_t frames = 0;
    std::size_t frames_off = 0;
    std::vector<double> waits_ms;
    for (const auto& segments : utterances) {
      const Track exact = render_track(model, segments, {.fps = fps});
      const Track approx = render_track(model, segments, {.fps = fps, .lookahead = lookahead});
      std::size_t segment = 0;
      for (std::size_t f = 0; f < exact.frame_count(); ++f) {
        // Wait: how long after its own time a frame can leave when phonemes arrive
        // as they are spoken (its segment k, plus `lookahead` more, must have ended).
        while (segment + 1 < segments.size() && segments[segment].end_us <= exact.t_us[f]) ++segment;
        const std::size_t needed = std::min(segments.size() - 1, segment + static_cast<std::size_t>(lookahead));
        waits_ms.push_back(static_cast<double>(segments[needed].end_us - exact.t_us[f]) * 1e-3);
        double frame_worst = 0.0;
        for (std::size_t c = 0; c < model.channel_count(); ++c) {
          // Errors relative to the channel's range, so tongue (−1..1) and muscles (0..1) compare.
          const double range = model.channels()[c].max - model.channels()[c].min;
          const double error = std::fabs(exact.frame_values(f)[c] - approx.frame_values(f)[c]) / range;
          squared += error * error;
          worst = std::max(worst, error);
          frame_worst = std::max(frame_worst, error);
          if (c == jaw) worst_jaw = std::max(worst_jaw, error);
          ++values;
        }
        ++frames;
        if (frame_worst > 0.01) ++frames_off;
      }
    }
    std::sort(waits_ms.begin(), waits_ms.end());
    double mean_wait = 0.0;
    for (double wait : waits_ms) mean_wait += wait / static_cast<double>(waits_ms.size());
    std::printf("| %d | %.0f | %.0f | %.0f | %.5f | %.4f | %.4f | %.1f %% |\n", lookahead, mean_wait,
                waits_ms[waits_ms.size() * 95 / 100], waits_ms.back(), std::sqrt(squared / static_cast<double>(values)),
                worst, worst_jaw, 100.0 * static_cast<double>(frames_off) / static_cast<double>(frames));
  }
  std::printf("\n%zu utterances, %d fps; errors are fractions of each channel's range.\n", utterances.size(), fps);
  return 0;
}
