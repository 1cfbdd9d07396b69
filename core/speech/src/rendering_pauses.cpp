// The pauses of the recording and the rendering, and the rendering edited to match
// (rendering_pauses.hpp).
#include "rendering_pauses.hpp"

#include <algorithm>
#include <cstdlib>
#include <limits>

namespace lipsync::speech {
namespace {

// Frames this far below the loudest are taken as pause when finding where speech starts and ends.
constexpr double kSpeechRangeDb = 35.0;
// A recording's pause: at least this long at a level kSpeechRangeDb under its loudest, µs.
constexpr std::int64_t kLeastPauseUs = 120'000;
// A pause of the recording that the warp matches to this much less pause of the rendering is
// put into the rendering, µs.
constexpr std::int64_t kLeastMissingPauseUs = 100'000;
// A pause of the rendering that the warp matches to this much less pause of the recording is cut
// from the rendering, µs. espeak-ng pauses between some words where a speaker runs on (110 ms after
// Catalan "pomes" before "i peres", and after Finnish "maitoa" before "ja banaaneja"); the warp then
// gives that digital silence to the next closure of the recording as quiet as it, and shifts the
// phones after by one: the /p/ of "peres" lands 193 ms late, the /b/ of "banaaneja" 199 ms. With the
// pause cut (and the warp done again) they are 2 and 1 ms late. espeak-ng's short pauses between
// words (10 to 25 ms) stay.
constexpr std::int64_t kLeastExtraPauseUs = 50'000;

}  // namespace

namespace detail {

std::vector<bool> pause_frames(const FeatureFrames& frames) {
  std::vector<bool> quiet(frames.size(), false);
  if (frames.level_db.size() != frames.size() || frames.level_db.empty()) return quiet;
  const double loudest = *std::max_element(frames.level_db.begin(), frames.level_db.end());
  for (std::size_t k = 0; k < quiet.size(); ++k) quiet[k] = frames.level_db[k] < loudest - kSpeechRangeDb;
  return quiet;
}

std::pair<PcmAudio, LabeledUtterance> with_pauses(const PcmAudio& audio, const LabeledUtterance& phones,
                                                  const LabeledUtterance& moved, std::vector<MissingPause> pauses,
                                                  const std::vector<ExtraPause>& cuts) {
  // Edits from the last phone back, so that each finds the times and indices before it unchanged.
  struct Edit {
    std::size_t phone;
    const MissingPause* pause;
    const ExtraPause* cut;
  };
  std::vector<Edit> edits;
  edits.reserve(pauses.size() + cuts.size());
  for (const MissingPause& pause : pauses) edits.push_back({pause.phone, &pause, nullptr});
  for (const ExtraPause& cut : cuts) {
    const bool crossed = std::any_of(pauses.begin(), pauses.end(), [&](const MissingPause& pause) {
      return pause.phone >= cut.first_phone && pause.phone <= cut.last_phone + 1;
    });
    if (!crossed) edits.push_back({cut.first_phone, nullptr, &cut});
  }
  std::sort(edits.begin(), edits.end(), [](const Edit& a, const Edit& b) { return a.phone > b.phone; });
  PcmAudio result_audio = audio;
  LabeledUtterance result_phones = phones;
  std::vector<LabeledInterval>& intervals = result_phones.intervals;
  const auto sample_at = [](std::int64_t us) { return static_cast<std::size_t>(us * kFeatureRateHz / 1'000'000); };
  std::size_t previous_phone = intervals.size();
  for (const Edit& edit : edits) {
    if (edit.cut != nullptr) {
      const ExtraPause& cut = *edit.cut;
      const std::int64_t from_us = moved.intervals[cut.first_phone].start_us;
      const std::int64_t to_us = moved.intervals[cut.last_phone].end_us;
      const std::size_t begin = sample_at((from_us + to_us - cut.duration_us) / 2);
      const std::size_t end = std::min(result_audio.samples.size(), begin + sample_at(cut.duration_us));
      const std::int64_t cut_begin_us = static_cast<std::int64_t>(begin) * 1'000'000 / kFeatureRateHz;
      const std::int64_t shift_us = static_cast<std::int64_t>(end - begin) * 1'000'000 / kFeatureRateHz;
      result_audio.samples.erase(result_audio.samples.begin() + static_cast<std::ptrdiff_t>(begin),
                                 result_audio.samples.begin() + static_cast<std::ptrdiff_t>(end));
      const auto moved_time = [&](std::int64_t t) {
        return t <= cut_begin_us ? t : std::max(cut_begin_us, t - shift_us);
      };
      for (std::size_t k = cut.first_phone; k < intervals.size(); ++k) {
        intervals[k].start_us = moved_time(intervals[k].start_us);
        intervals[k].end_us = moved_time(intervals[k].end_us);
      }
      // A pause of the run left empty goes (the run keeps at least a frame's length).
      for (std::size_t k = cut.last_phone + 1; k-- > cut.first_phone;) {
        if (intervals[k].end_us <= intervals[k].start_us)
          intervals.erase(intervals.begin() + static_cast<std::ptrdiff_t>(k));
      }
      continue;
    }
    const MissingPause& pause = *edit.pause;
    if (pause.phone == previous_phone) continue;
    previous_phone = pause.phone;
    const std::int64_t at_us = moved.intervals[pause.phone].start_us;
    const auto at_sample = sample_at(at_us);
    const auto samples = sample_at(pause.duration_us);
    result_audio.samples.insert(result_audio.samples.begin() + static_cast<std::ptrdiff_t>(at_sample), samples, 0);
    const std::int64_t shift_us = static_cast<std::int64_t>(samples) * 1'000'000 / kFeatureRateHz;
    for (std::size_t k = pause.phone; k < intervals.size(); ++k) {
      intervals[k].start_us += shift_us;
      intervals[k].end_us += shift_us;
    }
    if (intervals[pause.phone].label.empty()) {  // a pause of espeak-ng's own, lengthened
      intervals[pause.phone].start_us = at_us;
    } else if (intervals[pause.phone - 1].label.empty()) {
      intervals[pause.phone - 1].end_us = intervals[pause.phone].start_us;
    } else {
      intervals[pause.phone - 1].end_us = at_us;
      intervals.insert(intervals.begin() + static_cast<std::ptrdiff_t>(pause.phone),
                       LabeledInterval{"", at_us, intervals[pause.phone].start_us, intervals[pause.phone].line});
    }
  }
  return {std::move(result_audio), std::move(result_phones)};
}

}  // namespace detail

std::pair<std::size_t, std::size_t> speech_frames(const FeatureFrames& frames) {
  if (frames.level_db.empty()) return {0, 0};
  const double loudest = *std::max_element(frames.level_db.begin(), frames.level_db.end());
  std::size_t first = 0, last = frames.level_db.size() - 1;
  while (first < last && frames.level_db[first] < loudest - kSpeechRangeDb) ++first;
  while (last > first && frames.level_db[last] < loudest - kSpeechRangeDb) --last;
  return {first, last};
}

std::vector<MissingPause> missing_pauses(const WarpPath& path, const FeatureFrames& rendering,
                                         const std::vector<LabeledInterval>& phones, const FeatureFrames& recording) {
  std::vector<MissingPause> missing;
  const std::vector<bool> quiet = detail::pause_frames(recording), rendering_quiet = detail::pause_frames(rendering);
  const auto [speech_first, speech_last] = speech_frames(recording);
  for (std::size_t c0 = speech_first; c0 <= speech_last; ++c0) {
    if (!quiet[c0]) continue;
    std::size_t c1 = c0;
    while (c1 + 1 <= speech_last && quiet[c1 + 1]) ++c1;
    const std::size_t frames = c1 - c0 + 1;
    const std::size_t first = c0;
    c0 = c1;
    if (static_cast<std::int64_t>(frames) * kFeatureHopUs < kLeastPauseUs) continue;
    // The rendering's frames matched to the pause: how many are quiet, and which takes the most of it.
    std::size_t matched_quiet = 0, widest_row = 0, widest_columns = 0;
    for (std::size_t i = 0; i < path.first.size() && i < rendering_quiet.size(); ++i) {
      if (path.last[i] < first || path.first[i] > c1) continue;
      if (rendering_quiet[i]) ++matched_quiet;
      const std::size_t columns = std::min(path.last[i], c1) - std::max(path.first[i], first) + 1;
      if (columns > widest_columns) {
        widest_columns = columns;
        widest_row = i;
      }
    }
    if (matched_quiet >= frames) continue;
    const std::int64_t duration_us = static_cast<std::int64_t>(frames - matched_quiet) * kFeatureHopUs;
    if (duration_us < kLeastMissingPauseUs) continue;
    // The pause goes where the rendering's phone boundary nearest to that frame is.
    const std::int64_t widest_us = feature_frame_centre_us(widest_row);
    std::size_t best = 0;
    std::int64_t best_distance_us = std::numeric_limits<std::int64_t>::max();
    for (std::size_t k = 1; k < phones.size(); ++k) {
      const std::int64_t distance_us = std::abs(phones[k].start_us - widest_us);
      if (distance_us < best_distance_us) {
        best_distance_us = distance_us;
        best = k;
      }
    }
    if (best > 0) missing.push_back({best, duration_us});
  }
  return missing;
}

std::vector<ExtraPause> extra_pauses(const WarpPath& path, const FeatureFrames& rendering,
                                     const std::vector<LabeledInterval>& phones, const FeatureFrames& recording) {
  std::vector<ExtraPause> extra;
  const std::vector<bool> quiet = detail::pause_frames(recording), rendering_quiet = detail::pause_frames(rendering);
  // The recording's frames in a pause of its own: kLeastPauseUs or more at pause level, inside its
  // speech (a stop's closure is shorter).
  std::vector<bool> in_pause(quiet.size(), false);
  const auto [speech_first, speech_last] = speech_frames(recording);
  for (std::size_t c0 = speech_first; c0 <= speech_last && c0 < quiet.size(); ++c0) {
    if (!quiet[c0]) continue;
    std::size_t c1 = c0;
    while (c1 + 1 <= speech_last && quiet[c1 + 1]) ++c1;
    if (static_cast<std::int64_t>(c1 - c0 + 1) * kFeatureHopUs >= kLeastPauseUs) {
      for (std::size_t c = c0; c <= c1; ++c) in_pause[c] = true;
    }
    c0 = c1;
  }
  for (std::size_t k = 1; k + 1 < phones.size(); ++k) {
    if (!phones[k].label.empty()) continue;
    std::size_t last = k;
    while (last + 2 < phones.size() && phones[last + 1].label.empty()) ++last;
    const std::size_t first = k;
    k = last;
    if (phones[first - 1].label.empty() || phones[last + 1].label.empty()) continue;  // the padding's
    // The rendering's rows in the pause (centres inside it), their pause-level ones, and the
    // recording's pause frames matched to them.
    std::size_t quiet_rows = 0, row_begin = path.first.size(), row_end = 0;
    for (std::size_t i = 0; i < path.first.size() && i < rendering_quiet.size(); ++i) {
      const std::int64_t centre_us = feature_frame_centre_us(i);
      if (centre_us < phones[first].start_us || centre_us >= phones[last].end_us) continue;
      row_begin = std::min(row_begin, i);
      row_end = i + 1;
      if (rendering_quiet[i]) ++quiet_rows;
    }
    if (row_end <= row_begin) continue;
    std::size_t matched = 0;
    for (std::size_t c = path.first[row_begin]; c <= path.last[row_end - 1] && c < in_pause.size(); ++c) {
      if (in_pause[c]) ++matched;
    }
    if (matched >= quiet_rows) continue;
    const std::int64_t length_us = phones[last].end_us - phones[first].start_us;
    const std::int64_t duration_us =
        std::min(static_cast<std::int64_t>(quiet_rows - matched) * kFeatureHopUs, length_us - kFeatureHopUs);
    if (duration_us >= kLeastExtraPauseUs) extra.push_back({first, last, duration_us});
  }
  return extra;
}

}  // namespace lipsync::speech
