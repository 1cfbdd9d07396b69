// Alignment of a recording against espeak-ng's rendering of its transcript by dynamic time warping
// of MFCC frames (lipsync/speech/dtw_aligner.hpp). This file holds the warp, the carrying of a time
// across it, and the order of the steps: espeak-ng's rendering padded with pause and its stops started
// at their closures, a first warp, the pauses put into or cut from the rendering and a second warp
// when they bring the frames nearer (rendering_pauses.hpp), then the boundaries carried across and the
// rules that place them where the warp alone does not (carried_boundary_rules.hpp).
#include "lipsync/speech/dtw_aligner.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>

#include "alignable_audio.hpp"
#include "carried_boundary_rules.hpp"
#include "lipsync/error.hpp"
#include "rendering_pauses.hpp"

namespace lipsync::speech {
namespace {

// Silence added before and after espeak-ng's audio (which starts speaking at once), so the
// recording's leading and trailing pauses have pause to match, µs.
constexpr std::int64_t kSynthesisPaddingUs = 300'000;
// The recording may be this many times longer or shorter than the synthesis.
constexpr double kMostDurationRatio = 4.0;

enum Step : std::uint8_t { kDiagonal, kDown, kRight };
// Marks a stored step that paid StretchCost::cost (a → or ↓ past a run's free frames).
constexpr std::uint8_t kStretched = 4;

// The column of the band's centre line at row i: piecewise linear through the corners and
// the starts and ends of speech.
double centre_column(std::size_t i, const std::size_t (&rows)[4], const std::size_t (&columns)[4]) {
  for (int piece = 0; piece < 3; ++piece) {
    if (i <= rows[piece + 1] || piece == 2) {
      const double span = static_cast<double>(rows[piece + 1]) - static_cast<double>(rows[piece]);
      const double t = span <= 0 ? 1.0 : (static_cast<double>(i) - static_cast<double>(rows[piece])) / span;
      return static_cast<double>(columns[piece]) +
             t * (static_cast<double>(columns[piece + 1]) - static_cast<double>(columns[piece]));
    }
  }
  return static_cast<double>(columns[3]);
}

bool has_word_character(std::string_view text) {
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte >= 0x80 || std::isalnum(byte)) return true;
  }
  return false;
}

// `audio` with kSynthesisPaddingUs of silence before and after.
PcmAudio padded(const PcmAudio& audio) {
  const auto padding = static_cast<std::size_t>(audio.sample_rate_hz * kSynthesisPaddingUs / 1'000'000);
  PcmAudio result{audio.sample_rate_hz, std::vector<std::int16_t>(padding, 0)};
  result.samples.insert(result.samples.end(), audio.samples.begin(), audio.samples.end());
  result.samples.resize(result.samples.size() + padding, 0);
  return result;
}

// espeak-ng's rendering of the transcript, ready to warp: its audio (padded, at kFeatureRateHz), its
// phones (stops from their closures), each phone's start before that move (a stop's burst), its frames.
struct Rendering {
  PcmAudio audio;
  LabeledUtterance phones;
  std::vector<std::int64_t> bursts_us;
  FeatureFrames frames;
};

Rendering prepared_rendering(PcmAudio audio, LabeledUtterance phones) {
  Rendering rendering{std::move(audio), std::move(phones), {}, {}};
  rendering.bursts_us = detail::move_stop_starts_to_closures(rendering.audio, rendering.phones);
  rendering.frames = mfcc_features(rendering.audio);
  return rendering;
}

}  // namespace

WarpPath warp(const FeatureFrames& a, const FeatureFrames& b, std::size_t band_frames,
              std::pair<std::size_t, std::size_t> a_speech, std::pair<std::size_t, std::size_t> b_speech,
              const StretchCost& stretch) {
  const std::size_t rows = a.size(), columns = b.size();
  WarpPath path;
  if (rows == 0 || columns == 0) return path;
  const std::size_t corner_rows[4] = {0, a_speech.first, a_speech.second, rows - 1};
  const std::size_t corner_columns[4] = {0, b_speech.first, b_speech.second, columns - 1};

  // The band: columns [low[i], high[i]] of row i, each row reachable from the one above.
  std::vector<std::size_t> low(rows), high(rows);
  for (std::size_t i = 0; i < rows; ++i) {
    const double centre = centre_column(i, corner_rows, corner_columns);
    low[i] = static_cast<std::size_t>(std::max(0.0, std::floor(centre - static_cast<double>(band_frames))));
    high[i] = static_cast<std::size_t>(
        std::min(static_cast<double>(columns - 1), std::ceil(centre + static_cast<double>(band_frames))));
  }
  low[0] = 0;
  high[rows - 1] = columns - 1;
  for (std::size_t i = 1; i < rows; ++i) low[i] = std::max(low[i], low[i - 1]);
  for (std::size_t i = rows - 1; i-- > 0;) {
    high[i] = std::min(high[i], high[i + 1]);
    if (low[i + 1] > 0) high[i] = std::max(high[i], low[i + 1] - 1);
  }

  std::vector<std::size_t> offset(rows + 1, 0);
  for (std::size_t i = 0; i < rows; ++i) offset[i + 1] = offset[i] + (high[i] - low[i] + 1);
  std::vector<std::uint8_t> steps(offset[rows]);
  constexpr double kUnreachable = std::numeric_limits<double>::infinity();
  std::vector<double> previous(columns, kUnreachable), current(columns, kUnreachable);
  // The run of → or ↓ steps that the cheapest way into each cell ends with: +n after n ↓ steps (b's
  // frame j matched to n + 1 frames of a), −n after n → steps, 0 after ↘. A cell keeps only the run of
  // its cheapest way in, not one cost per run length (an approximation that keeps the warp's time and
  // memory).
  std::vector<std::int32_t> previous_run(columns, 0), current_run(columns, 0);
  const std::vector<bool> a_quiet = detail::pause_frames(a), b_quiet = detail::pause_frames(b);
  const auto free_frames = static_cast<std::int32_t>(stretch.free_frames);
  for (std::size_t i = 0; i < rows; ++i) {
    for (std::size_t j = low[i]; j <= high[i]; ++j) {
      const double distance = frame_distance(a, i, b, j);
      // Runs over pause-level frames are free: pauses and closures differ in length between speakers.
      const double run_cost = a_quiet[i] || b_quiet[j] ? 0.0 : stretch.cost;
      double best = kUnreachable;
      std::uint8_t step = kDiagonal;
      std::int32_t run = 0;
      if (i == 0 && j == 0) best = distance;
      if (i > 0 && j > 0 && j - 1 >= low[i - 1] && j - 1 <= high[i - 1] && previous[j - 1] + 2 * distance < best) {
        best = previous[j - 1] + 2 * distance;
      }
      if (i > 0 && j >= low[i - 1] && j <= high[i - 1]) {
        const std::int32_t down_run = std::max(previous_run[j], 0) + 1;
        const bool stretched = down_run > free_frames;
        if (const double cost = previous[j] + distance + (stretched ? run_cost : 0.0); cost < best) {
          best = cost;
          step = kDown | (stretched && run_cost > 0 ? kStretched : 0);
          run = down_run;
        }
      }
      if (j > low[i]) {
        const std::int32_t right_run = std::max(-current_run[j - 1], 0) + 1;
        const bool stretched = right_run > free_frames;
        if (const double cost = current[j - 1] + distance + (stretched ? run_cost : 0.0); cost < best) {
          best = cost;
          step = kRight | (stretched && run_cost > 0 ? kStretched : 0);
          run = -right_run;
        }
      }
      current[j] = best;
      current_run[j] = run;
      steps[offset[i] + (j - low[i])] = step;
    }
    std::swap(previous, current);
    std::swap(previous_run, current_run);
  }
  const double total_cost = previous[columns - 1];
  // The distance of unrelated frames: every frame of a against b's frames at a fixed stride.
  double sum = 0.0;
  std::size_t pairs = 0;
  const std::size_t stride = std::max<std::size_t>(1, columns / 64);
  for (std::size_t i = 0; i < rows; ++i) {
    for (std::size_t j = i % stride; j < columns; j += stride, ++pairs) sum += frame_distance(a, i, b, j);
  }
  path.unrelated_distance = sum / static_cast<double>(pairs);

  path.first.assign(rows, 0);
  path.last.assign(rows, 0);
  std::size_t i = rows - 1, j = columns - 1;
  path.last[i] = j;
  path.first[i] = j;
  double stretch_paid = 0.0;  // what the path paid for its runs, left out of its mean distance
  while (i > 0 || j > 0) {
    const std::uint8_t stored = steps[offset[i] + (j - low[i])];
    if ((stored & kStretched) != 0) stretch_paid += stretch.cost;
    const auto step = static_cast<Step>(stored & ~kStretched);
    if (step == kRight) {
      --j;
    } else {
      if (step == kDiagonal) --j;
      --i;
      path.last[i] = j;
    }
    path.first[i] = j;
  }
  path.mean_distance = (total_cost - stretch_paid) / static_cast<double>(rows + columns);
  return path;
}

std::int64_t carry_time_us(const WarpPath& path, std::int64_t a_us) {
  const std::size_t rows = path.first.size();
  if (rows == 0) return a_us;
  const double position = static_cast<double>(a_us - feature_frame_centre_us(0)) / kFeatureHopUs;
  if (position <= 0)
    return std::max<std::int64_t>(0, feature_frame_centre_us(path.first[0]) + (a_us - feature_frame_centre_us(0)));
  if (position >= static_cast<double>(rows - 1)) {
    return feature_frame_centre_us(path.last[rows - 1]) + (a_us - feature_frame_centre_us(rows - 1));
  }
  const auto row = static_cast<std::size_t>(std::floor(position));  // between rows `row` and `row + 1`
  const double fraction = position - static_cast<double>(row);
  const double from = static_cast<double>(path.last[row]);
  const double to = static_cast<double>(path.first[row + 1]);
  const double column = from + fraction * (to - from);
  return feature_frame_centre_us(0) + static_cast<std::int64_t>(std::llround(column * kFeatureHopUs));
}

namespace {

// The steps of align_speech_to_synthesis, in order.

// espeak-ng's rendering of the transcript, once the transcript and the audio passed the checks
// and the two are no more than kMostDurationRatio apart in length.
Synthesis spoken_transcript(const PcmAudio& input, const std::string& source, const DtwAlignmentOptions& options) {
  const std::string& voice = options.synthesis.voice;
  if (!has_word_character(options.transcript)) {
    throw InputError(source, 0, "the transcript is empty: alignment with --voice " + voice + " needs the words spoken");
  }
  detail::check_alignable_audio(input, source, options.max_duration_s, "alignment");

  Synthesis synthesis;
  try {
    synthesis = synthesize(options.transcript, options.synthesis);
  } catch (const InputError& error) {
    throw InputError(source, 0, "cannot speak the transcript with espeak-ng voice '" + voice + "': " + error.message());
  }
  if (synthesis.phonemes.intervals.empty()) {
    throw InputError(source, 0, "espeak-ng voice '" + voice + "' spoke no phonemes for the transcript");
  }
  const double duration_s = double(input.samples.size()) / input.sample_rate_hz;
  const double synthesis_s = double(synthesis.audio.samples.size()) / synthesis.audio.sample_rate_hz;
  if (duration_s > kMostDurationRatio * synthesis_s || synthesis_s > kMostDurationRatio * duration_s) {
    char text[400];
    std::snprintf(text, sizeof text,
                  "the recording (%.1f s) cannot be the transcript: espeak-ng voice '%s' speaks it in %.1f s "
                  "(more than %.0f times longer or shorter)",
                  duration_s, voice.c_str(), synthesis_s, kMostDurationRatio);
    throw InputError(source, 0, text);
  }
  return synthesis;
}

// The rendering's phones on its padded audio (`spoken_end_us` long): moved by the padding, which
// is pause, merged with a pause espeak-ng begins or ends with.
LabeledUtterance padded_phones(const LabeledUtterance& phonemes, std::int64_t spoken_end_us) {
  LabeledUtterance synthesis_phones = phonemes;
  for (LabeledInterval& interval : synthesis_phones.intervals) {
    interval.start_us += kSynthesisPaddingUs;
    interval.end_us += kSynthesisPaddingUs;
  }
  std::vector<LabeledInterval>& padded_phones = synthesis_phones.intervals;
  if (padded_phones.front().label.empty()) {
    padded_phones.front().start_us = 0;
  } else {
    padded_phones.insert(padded_phones.begin(), LabeledInterval{"", 0, kSynthesisPaddingUs, 0});
  }
  if (padded_phones.back().label.empty()) {
    padded_phones.back().end_us = spoken_end_us;
  } else {
    padded_phones.push_back(LabeledInterval{"", padded_phones.back().end_us, spoken_end_us, 0});
  }
  return synthesis_phones;
}

// The rendering the recording is warped to and that warp: the first, or the second with the
// recording's pauses put into the rendering and its own cut where that brings the frames nearer.
std::pair<Rendering, WarpPath> best_warp(const PcmAudio& spoken, const LabeledUtterance& synthesis_phones,
                                         const FeatureFrames& recording_frames, const DtwAlignmentOptions& options) {
  const auto band_frames = static_cast<std::size_t>(std::max(1.0, options.band_s * 1e6 / kFeatureHopUs));
  const auto warp_to_recording = [&](const Rendering& rendering) {
    return warp(rendering.frames, recording_frames, band_frames, speech_frames(rendering.frames),
                speech_frames(recording_frames), options.stretch);
  };
  Rendering rendering = prepared_rendering(spoken, synthesis_phones);
  WarpPath path = warp_to_recording(rendering);
  const std::vector<MissingPause> pauses =
      missing_pauses(path, rendering.frames, rendering.phones.intervals, recording_frames);
  const std::vector<ExtraPause> cuts =
      extra_pauses(path, rendering.frames, rendering.phones.intervals, recording_frames);
  if (!pauses.empty() || !cuts.empty()) {
    auto [paused_audio, paused_phones] = detail::with_pauses(spoken, synthesis_phones, rendering.phones, pauses, cuts);
    Rendering paused = prepared_rendering(std::move(paused_audio), std::move(paused_phones));
    WarpPath paused_path = warp_to_recording(paused);
    if (paused_path.mean_distance <= path.mean_distance) {
      rendering = std::move(paused);
      path = std::move(paused_path);
    }
  }
  return {std::move(rendering), std::move(path)};
}

// The note saying how near the warp's frames are; InputError when they are too far apart for the
// recording to say the transcript.
std::string checked_match(const WarpPath& path, const std::string& source, const DtwAlignmentOptions& options) {
  const std::string& voice = options.synthesis.voice;
  char text[400];
  if (path.mean_distance > options.max_distance_ratio * path.unrelated_distance) {
    std::snprintf(text, sizeof text,
                  "the recording does not match the transcript as espeak-ng voice '%s' speaks it (the best warp's "
                  "frames are %.0f %% as far apart as unrelated frames, at most %.0f %% accepted): is it speech, "
                  "saying the transcript, in that voice's language?",
                  voice.c_str(), 100.0 * path.mean_distance / path.unrelated_distance,
                  100.0 * options.max_distance_ratio);
    throw InputError(source, 0, text);
  }
  std::snprintf(text, sizeof text,
                "aligned against espeak-ng voice '%s' (mean distance along the warp %.2f, %.0f %% of unrelated "
                "frames)",
                voice.c_str(), path.mean_distance, 100.0 * path.mean_distance / path.unrelated_distance);
  return text;
}

// The rendering's phones carried across the warp to the recording (`end_us` long), by the rules of
// carried_boundary_rules.hpp and the /m/ murmur; an empty phone is left out.
std::vector<LabeledInterval> carried_phones(const Rendering& rendering, const WarpPath& path, const PcmAudio& recording,
                                            const FeatureFrames& recording_frames, std::int64_t end_us) {
  const std::vector<LabeledInterval>& spoken_phones = rendering.phones.intervals;
  std::vector<std::int64_t> bounds = detail::carried_bounds(path, spoken_phones, rendering.bursts_us, end_us,
                                                            detail::pause_frames(recording_frames), recording);
  start_bilabial_nasals_at_murmur(bounds, spoken_phones, formant_band_levels_db(recording, 10'000, 1'000));
  std::vector<LabeledInterval> phones;
  for (std::size_t k = 0; k < spoken_phones.size(); ++k) {
    LabeledInterval interval = spoken_phones[k];
    interval.start_us = bounds[k];
    interval.end_us = bounds[k + 1];
    interval.line = static_cast<int>(k + 1);
    if (interval.end_us > interval.start_us) phones.push_back(std::move(interval));
  }
  return phones;
}

}  // namespace

Alignment align_speech_to_synthesis(const PcmAudio& input, std::string_view source_view,
                                    const DtwAlignmentOptions& options) {
  const std::string source(source_view);
  const Synthesis synthesis = spoken_transcript(input, source, options);

  Alignment result;
  result.phones.source = source;
  result.phones.phone_set = phone_set_for_voice(options.synthesis.voice);
  // How espeak-ng read the transcript, when that needs saying (words read by another language's rules).
  for (const std::string& note : synthesis.notes) result.notes.push_back("the transcript: " + note);
  if (input.sample_rate_hz != kFeatureRateHz) {
    result.notes.push_back("resampled from " + std::to_string(input.sample_rate_hz) + " Hz to " +
                           std::to_string(kFeatureRateHz) + " Hz for the alignment");
  }
  const PcmAudio recording = resample(input, kFeatureRateHz);
  const PcmAudio spoken = padded(resample(synthesis.audio, kFeatureRateHz));
  const FeatureFrames recording_frames = mfcc_features(recording);
  const auto [rendering, path] =
      best_warp(spoken, padded_phones(synthesis.phonemes, spoken.duration_us()), recording_frames, options);
  result.notes.push_back(checked_match(path, source, options));

  result.phones.intervals = carried_phones(rendering, path, recording, recording_frames, input.duration_us());
  if (result.phones.intervals.empty()) throw InputError(source, 0, "the audio is too short for the transcript");
  result.phones.intervals.front().start_us = 0;
  result.phones.intervals.back().end_us = input.duration_us();
  if (options.refine_closures) result.refined = detail::refine_lip_phones(recording, result.phones, options.refiner);
  return result;
}

}  // namespace lipsync::speech
