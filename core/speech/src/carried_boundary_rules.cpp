// The rules applied to the boundaries carried across the warp (carried_boundary_rules.hpp).
#include "carried_boundary_rules.hpp"

#include <algorithm>
#include <optional>
#include <string>
#include <utility>

#include "espeak_labels.hpp"

namespace lipsync::speech {

using detail::is_nasal;
using detail::is_voiced_closure;
using detail::is_vowel;
using detail::lip_phone_for_refiner;
using detail::may_be_squeezed_into_closure;
using detail::starts_with_closure;

namespace {

// The shortest a carried phoneme may become, µs.
constexpr std::int64_t kMinPhoneUs = 1'000;
// How far before espeak-ng's start of a stop its closure is looked for, µs.
constexpr std::int64_t kStopClosureSearchUs = 150'000;
// The smallest fall of the formant band's level taken as a stop's closure, dB.
constexpr double kStopClosureStepDb = 10.0;

// The steepest fall of the formant band's level (`level_db`, 10 ms windows every ms) within
// [earliest_ms, start_ms − 5 ms] larger than kStopClosureStepDb: a stop's closure before its
// burst at start_ms; −1 when there is none.
std::int64_t closure_before_ms(const std::vector<double>& level_db, std::int64_t start_ms, std::int64_t earliest_ms) {
  double best_fall_db = kStopClosureStepDb;
  std::int64_t best_ms = -1;
  for (std::int64_t t = std::max<std::int64_t>(earliest_ms, 10);
       t <= start_ms - 5 && t < static_cast<std::int64_t>(level_db.size()); ++t) {
    const double fall = level_db[t - 10] - level_db[t];
    if (fall > best_fall_db) {
      best_fall_db = fall;
      best_ms = t;
    }
  }
  return best_ms;
}

}  // namespace

namespace detail {

std::vector<std::int64_t> move_stop_starts_to_closures(const PcmAudio& audio, LabeledUtterance& phones) {
  std::vector<LabeledInterval>& intervals = phones.intervals;
  std::vector<std::int64_t> bursts_us;
  bursts_us.reserve(intervals.size());
  for (const LabeledInterval& interval : intervals) bursts_us.push_back(interval.start_us);
  const std::vector<double> level_db = formant_band_levels_db(audio, 10'000, 1'000);  // window [t, t+10 ms)
  if (level_db.size() < 20) return bursts_us;
  for (std::size_t k = 1; k < intervals.size(); ++k) {
    if (!starts_with_closure(intervals[k].label)) continue;
    const std::int64_t start_ms = intervals[k].start_us / 1000;
    const std::int64_t best_ms = closure_before_ms(
        level_db, start_ms, std::max(start_ms - kStopClosureSearchUs / 1000, intervals[k - 1].start_us / 1000 + 10));
    if (best_ms < 0) continue;
    intervals[k].start_us = best_ms * 1000;
    intervals[k - 1].end_us = best_ms * 1000;
  }
  return bursts_us;
}

}  // namespace detail

namespace {

// A stop after a pause has no fall of the level to mark its closure, in either audio (both
// start it at the burst): its closure is taken to last this long, a typical closure of a stop
// that begins an utterance (longer than espeak-ng's closures between vowels), µs.
constexpr std::int64_t kClosureAfterPauseUs = 80'000;

// A stop after a pause starts, in both audios, at its burst: the closure is silent, like the pause.
// Its start moves back into the pause by kClosureAfterPauseUs (the pause keeps kMinPhoneUs at least).
void open_closures_after_pauses(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones) {
  for (std::size_t k = 1; k < phones.size(); ++k) {
    if (!phones[k - 1].label.empty() || !starts_with_closure(phones[k].label)) continue;
    bounds[k] = std::max(bounds[k] - kClosureAfterPauseUs, bounds[k - 1] + kMinPhoneUs);
  }
}

// A stop after a nasal (/m b/, /n d/) has no fall of the level to mark its closure either: the
// nasal's closure goes on into it, and espeak-ng's nasal lasts until the burst. Its closure is taken
// to last this long, a typical closure of a voiced stop (chosen on the four sentences of Italian
// and Hindi whose /m b/ arrived at their bursts, 58 and 73 ms after Festival's closures), µs.
constexpr std::int64_t kClosureAfterNasalUs = 60'000;

// A stop after a nasal arrives at (or just before) the recording's burst: its closure is the nasal's
// and shows no fall of the level. It starts kClosureAfterNasalUs before its burst carried across,
// unless it is earlier already (the nasal keeps kMinPhoneUs at least).
void open_closures_after_nasals(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                const std::vector<std::int64_t>& bursts_us, const WarpPath& path) {
  for (std::size_t k = 1; k < phones.size(); ++k) {
    if (!is_nasal(phones[k - 1].label) || !starts_with_closure(phones[k].label)) continue;
    const std::int64_t closure_us = carry_time_us(path, bursts_us[k]) - kClosureAfterNasalUs;
    bounds[k] = std::max(std::min(bounds[k], closure_us), bounds[k - 1] + kMinPhoneUs);
  }
}

// A nasal or a voiced stop after a pause is heard from where the recording leaves pause level: the
// nasal's murmur or the stop's voicing bar, under a closure that espeak-ng's rendering starts
// softer or later, so that the warp carries its start into the recording's murmur. Such a phone
// whose carried start is in the recording's speech, with pause-level frames within
// kClosureAfterPauseUs before it, starts after the last of those (Russian "Бабушка" after the
// leading pause: 1 ms early, where kClosureAfterPauseUs before its burst is 55 ms late). Only such
// phones: applied to every phone after a pause, it moves espeak-ng's own fricatives and vowels
// before their labels (the 120-wpm test's p95 32.3 ms instead of 26.7).
void start_at_speech_after_pauses(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                  const std::vector<bool>& recording_quiet) {
  for (std::size_t k = 1; k < phones.size(); ++k) {
    if (!phones[k - 1].label.empty() || !is_voiced_closure(phones[k].label) || recording_quiet.empty()) continue;
    const auto frame_at = [&](std::int64_t us) {
      const std::int64_t frame = (us - feature_frame_centre_us(0) + kFeatureHopUs / 2) / kFeatureHopUs;
      return static_cast<std::size_t>(std::clamp<std::int64_t>(frame, 0, std::int64_t(recording_quiet.size()) - 1));
    };
    std::size_t frame = frame_at(bounds[k]);
    if (recording_quiet[frame]) continue;
    while (frame > 0 && !recording_quiet[frame - 1] &&
           bounds[k] - feature_frame_centre_us(frame - 1) <= kClosureAfterPauseUs) {
      --frame;
    }
    if (frame == 0 || !recording_quiet[frame - 1]) continue;
    const std::int64_t onset_us = feature_frame_centre_us(frame) - kFeatureHopUs / 2;
    bounds[k] = std::max(std::min(bounds[k], onset_us), bounds[k - 1] + kMinPhoneUs);
  }
}

// A voiced /b/ whose carried start lies inside a voiced closure of the recording starts where that
// closure does (start_voiced_bilabials_at_closures): the closure is the formant band (400–3500 Hz)
// this much under the sound before it and the sound after it (the release), dB,
constexpr double kVoicedClosureDb = 10.0;
// its frames within this much of the formant band's level at the carried start, dB,
constexpr double kVoicedClosureSpreadDb = 6.0;
// voiced: the level below 400 Hz (the voicing bar) at most this much under its loudest in the
// recording, dB, and not falling by kVoicedClosureDb from the carried start back; looked for this
// far each side of the carried start, ms; the phones it crosses are left this long before it, µs.
constexpr double kVoicingBarRangeDb = 25.0;
constexpr std::int64_t kVoicedClosureSearchMs = 150;
constexpr std::int64_t kSqueezedPhoneUs = 10'000;
// A closure this short is a tap's (Catalan's /ɾ/: the formant band dips for 20 to 25 ms), not a /b/'s
// (60 to 90 ms in Festival's Catalan), ms.
constexpr std::int64_t kShortestVoicedClosureMs = 40;

// The recording's levels in the formant band and below 400 Hz (the voicing bar), dB, of the 10 ms
// windows [t, t + 10 ms) at every millisecond t.
struct BandLevels {
  std::vector<double> formants;
  std::vector<double> lows;

  [[nodiscard]] std::int64_t size() const { return static_cast<std::int64_t>(formants.size()); }
  // The levels of the 10 ms window centred at t ms.
  [[nodiscard]] double formant(std::int64_t t) const {
    return formants[std::clamp<std::int64_t>(t - 5, 0, size() - 1)];
  }
  [[nodiscard]] double low(std::int64_t t) const { return lows[std::clamp<std::int64_t>(t - 5, 0, size() - 1)]; }
  // The formant band's loudest level over [from, to) ms.
  [[nodiscard]] double loudest_formant(std::int64_t from, std::int64_t to) const {
    double loudest = -1e300;
    for (std::int64_t t = from; t < to; ++t) loudest = std::max(loudest, formant(t));
    return loudest;
  }
};

// A voiced closure of the recording around a /b/'s carried start `carried_ms`: back to `begin_ms` the
// formant band holds within kVoicedClosureSpreadDb of `level_db`, its level at the carried start.
struct VoicedClosure {
  std::int64_t carried_ms;
  std::int64_t begin_ms;
  double level_db;

  [[nodiscard]] bool holds(const BandLevels& levels, std::int64_t t) const {
    return levels.formant(t) <= level_db + kVoicedClosureSpreadDb;
  }
};

// The voiced closure around `carried_ms`, if there is one: the voicing bar there within
// kVoicingBarRangeDb of `loudest_low_db`; the formant band held for under kVoicedClosureSearchMs after
// it, to a release kVoicedClosureDb louder within 20 ms; followed back, while the voicing bar does not
// fall by kVoicedClosureDb, for under kVoicedClosureSearchMs, kShortestVoicedClosureMs or more in all.
std::optional<VoicedClosure> voiced_closure_around(const BandLevels& levels, std::int64_t carried_ms,
                                                   double loudest_low_db) {
  const std::int64_t t0 = carried_ms;
  VoicedClosure closure{t0, t0, levels.formant(t0)};
  const double voicing_db = levels.low(t0);
  if (voicing_db < loudest_low_db - kVoicingBarRangeDb) return std::nullopt;
  std::int64_t release = t0;
  while (release < t0 + kVoicedClosureSearchMs && closure.holds(levels, release + 1)) ++release;
  if (release >= t0 + kVoicedClosureSearchMs ||
      levels.loudest_formant(release, release + 20) - closure.level_db < kVoicedClosureDb) {
    return std::nullopt;
  }
  std::int64_t begin = t0;
  while (begin > t0 - kVoicedClosureSearchMs && closure.holds(levels, begin - 1) &&
         levels.low(begin - 1) >= voicing_db - kVoicedClosureDb)
    --begin;
  if (begin <= t0 - kVoicedClosureSearchMs || release - begin < kShortestVoicedClosureMs) return std::nullopt;
  closure.begin_ms = begin;
  return closure;
}

// Where `closure` begins after the formant band's fall from the sound before (kVoicedClosureDb louder
// within 20 ms, else none): at the fall's onset, where the 10 ms fall is down to 0.4 of its steepest
// (looked for from 20 ms before the closure's begin to 10 ms after), less 3 ms.
std::optional<std::int64_t> onset_of_formant_fall_ms(const BandLevels& levels, const VoicedClosure& closure) {
  const std::int64_t begin = closure.begin_ms;
  if (levels.loudest_formant(begin - 20, begin) - closure.level_db < kVoicedClosureDb) return std::nullopt;
  const auto fall = [&](std::int64_t t) { return levels.formant(t - 5) - levels.formant(t + 5); };
  std::int64_t steepest = begin - 20;
  for (std::int64_t t = begin - 20; t <= begin + 10; ++t) {
    if (fall(t) > fall(steepest)) steepest = t;
  }
  std::int64_t onset = steepest;
  while (onset - 1 > begin - 40 && fall(onset - 1) >= 0.4 * fall(steepest)) --onset;
  return onset - 3;
}

// Where `closure` begins after a voiceless stop's silence (the formant band as low before the voicing
// bar, back to a sound kVoicedClosureDb louder within 20 ms and under kVoicedClosureSearchMs before
// the carried start, else none): at the steepest 10 ms rise of the voicing bar from the silence's
// start to 10 ms after the closure's begin.
std::optional<std::int64_t> voicing_bar_rise_ms(const BandLevels& levels, const VoicedClosure& closure) {
  const std::int64_t earliest = closure.carried_ms - kVoicedClosureSearchMs;
  std::int64_t silence = closure.begin_ms;
  while (silence > earliest && closure.holds(levels, silence - 1)) --silence;
  if (silence <= earliest || levels.loudest_formant(silence - 20, silence) - closure.level_db < kVoicedClosureDb) {
    return std::nullopt;
  }
  const auto rise = [&](std::int64_t t) { return levels.low(t + 5) - levels.low(t - 5); };
  std::int64_t steepest = silence;
  for (std::int64_t t = silence; t <= closure.begin_ms + 10; ++t) {
    if (rise(t) > rise(steepest)) steepest = t;
  }
  return steepest;
}

// Starts phones[k] at `start_us`, before its carried start, with the phones the closure holds before it
// (the one holding `start_us` and those after it) squeezed in: kSqueezedPhoneUs each before it, or
// kMinPhoneUs where there is no room for that. Nothing moves when one of them may not be squeezed into
// a closure, or when there is no room.
void start_at_closure(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones, std::size_t k,
                      std::int64_t start_us) {
  if (start_us >= bounds[k]) return;
  std::size_t holder = k - 1;
  while (holder > 0 && bounds[holder] > start_us) --holder;
  bool squeezable = true;
  for (std::size_t j = holder; j < k; ++j) squeezable = squeezable && may_be_squeezed_into_closure(phones[j].label);
  const auto crossed = static_cast<std::int64_t>(k - 1 - holder);
  std::int64_t spacing = kSqueezedPhoneUs;
  if (start_us - crossed * spacing < bounds[holder] + kSqueezedPhoneUs) spacing = kMinPhoneUs;
  if (!squeezable || start_us - crossed * spacing < bounds[holder] + kMinPhoneUs) return;
  bounds[k] = start_us;
  for (std::size_t j = k - 1; j > holder; --j) bounds[j] = bounds[j + 1] - spacing;
}

// An /m/'s murmur is quieter than the vowel before it in the formant band (400–3500 Hz): the lips are
// closed and the sound leaves through the nose. espeak-ng's short vowels are farther from a speaker's
// than its /m/ is, so the warp may match /m/ frames to the end of the recording's vowel (Russian "в
// большом" /o m/: two /m/ frames take 100 ms of Festival's /o/ in runs of 5 and 8 frames, within the
// run cost's free frames, and the /m/ lands 104 ms early). An /m/ after a vowel whose carried start is
// inside the vowel (the level there within kMurmurInVowelDb of the loudest from the vowel's carried
// start to kMurmurInVowelUs after it, and falling by no more than kMurmurSteadyDb over those
// kMurmurInVowelUs) starts where the level first falls kMurmurFallDb under that loudest, at the steepest 10 ms fall
// within 10 ms of that, when this is inside its carried interval and within kMurmurSearchUs of its start. The Russian
// /m/ is then 9 ms late; every other /p b m/ of the seven voices starts at a falling level already and is left alone
// (without the check that the level is not falling, Catalan's /ə m/ of "Em poso", whose level falls slowly into the
// murmur, would start 72 ms late). Only /m/: a velar nasal's murmur keeps the formant band up until the stop's
// closure (applied to every nasal, the rule starts Czech "Maminka" /ŋ/ before its /k/ 46 ms late).
constexpr double kMurmurInVowelDb = 4.0;
constexpr double kMurmurSteadyDb = 2.0;
constexpr std::int64_t kMurmurInVowelUs = 30'000;
constexpr double kMurmurFallDb = 6.0;
constexpr std::int64_t kMurmurSearchUs = 150'000;

}  // namespace

// A voiced /b/ (espeak-ng's /b/, or the /β/ it says for Catalan's and Spanish's /b/ between vowels and
// after some consonants) whose carried start lies inside a voiced closure of the recording starts where
// that closure begins, and the phones of espeak-ng's the warp put inside the closure before it are
// squeezed against it. Festival's Catalan speaker says "molt bo", "al bosc", "el bon" as [l b] with no
// /t/ or vowel between: espeak-ng's [l t β], [ɐ l β] and the quiet closure of its /t/ take the start of
// the recording's closure, and the /β/, a fricative as loud as a vowel in espeak-ng's audio, goes to
// the burst, 37 to 66 ms late, out of the closure refiner's reach (it looks 50 ms around the warp's
// boundary, and not before the phone before). The closure shows in the sound: the formant band falls
// 13 to 21 dB and stays down to the burst, while the level below 400 Hz (the voicing bar) holds within
// 6 dB of the /l/'s. So: where the formant band at the carried start is kVoicedClosureDb under both the
// sound before and the release after, and the low band within kVoicingBarRangeDb of its loudest
// (voiced), the closure is followed back while the formant band stays within kVoicedClosureSpreadDb of
// that level and the voicing bar holds. It begins at a fall of the formant band (the /b/ starts at that
// fall's onset, where it is down to 0.4 of its steepest, less 3 ms, as the closure refiner places a
// closure), or, after a voiceless stop's silence, where the voicing bar rises ("barret blau": Festival
// says [t b], the /t/'s silence and then 75 ms of voicing bar, where the warp puts the /β/ 73 ms
// late). Only stops and sonorants may lie in the closure: a voiced fricative or nasal before the /b/
// is low in the formant band and voiced too (Russian "в большом" /v b/). A voiceless closure is left
// alone: a /p b/ after a stop with no release shares one silence with it (Finnish "menivat
// puistoon"), where the speaker closes the lips is not heard. A dip shorter than
// kShortestVoicedClosureMs is a tap's. On Festival's voices (signed errors against its labels) the
// rule starts "al bosc", "molt bo", "el bon" /l b/ -2, -4, -4 ms off, "barret blau" /t b/ +2, "molt
// bonica" /l b/ -4, "mar blau" /r b/ -11 and Russian "большой белый" /j bʲ/ -1 ms; it moves no other
// closure of any voice, in sample or held out.
void start_voiced_bilabials_at_closures(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                        const PcmAudio& recording) {
  const BandLevels levels{formant_band_levels_db(recording, 10'000, 1'000),
                          low_band_levels_db(recording, 10'000, 1'000)};
  if (levels.size() == 0 || levels.lows.size() != levels.formants.size() || bounds.size() != phones.size() + 1) return;
  const double loudest_low_db = *std::max_element(levels.lows.begin(), levels.lows.end());
  for (std::size_t k = 2; k + 1 < phones.size(); ++k) {
    if (lip_phone_for_refiner(phones[k].label) != "B" || phones[k - 1].label.empty() || is_nasal(phones[k - 1].label))
      continue;
    const std::optional<VoicedClosure> closure = voiced_closure_around(levels, bounds[k] / 1000, loudest_low_db);
    if (!closure) continue;
    const bool after_sound = !closure->holds(levels, closure->begin_ms - 1);
    const std::optional<std::int64_t> start_ms =
        after_sound ? onset_of_formant_fall_ms(levels, *closure) : voicing_bar_rise_ms(levels, *closure);
    if (start_ms) start_at_closure(bounds, phones, k, *start_ms * 1000);
  }
}

void start_bilabial_nasals_at_murmur(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                     const std::vector<double>& level_db) {
  const auto size = static_cast<std::int64_t>(level_db.size());
  for (std::size_t k = 1; k + 1 < phones.size(); ++k) {
    if (lip_phone_for_refiner(phones[k].label) != "M" || !is_vowel(phones[k - 1].label)) continue;
    const std::int64_t vowel_ms = bounds[k - 1] / 1000, start_ms = bounds[k] / 1000;
    const std::int64_t inside_ms = start_ms + kMurmurInVowelUs / 1000;
    const std::int64_t last_ms = std::min({bounds[k + 1] / 1000 - 5, start_ms + kMurmurSearchUs / 1000, size - 1});
    if (start_ms < 10 || inside_ms >= last_ms) continue;
    const auto from = level_db.begin();
    const double loudest_db = *std::max_element(from + vowel_ms, from + inside_ms + 1);
    if (level_db[start_ms] < loudest_db - kMurmurInVowelDb ||
        *std::min_element(from + start_ms, from + inside_ms + 1) < level_db[start_ms] - kMurmurSteadyDb) {
      continue;
    }
    std::int64_t fallen_ms = inside_ms;
    while (fallen_ms <= last_ms && level_db[fallen_ms] > loudest_db - kMurmurFallDb) ++fallen_ms;
    if (fallen_ms > last_ms) continue;
    std::int64_t best_ms = fallen_ms;
    double best_fall_db = -1e9;
    for (std::int64_t t = std::max(fallen_ms - 10, inside_ms); t <= std::min(fallen_ms + 10, last_ms); ++t) {
      if (const double fall = level_db[t - 10] - level_db[t]; fall > best_fall_db) {
        best_fall_db = fall;
        best_ms = t;
      }
    }
    bounds[k] = std::min(best_ms * 1000, bounds[k + 1] - kMinPhoneUs);
  }
}

namespace detail {

std::vector<std::int64_t> carried_bounds(const WarpPath& path, const std::vector<LabeledInterval>& phones,
                                         const std::vector<std::int64_t>& bursts_us, std::int64_t end_us,
                                         const std::vector<bool>& recording_quiet, const PcmAudio& recording) {
  const std::size_t count = phones.size();
  std::vector<std::int64_t> bounds(count + 1);
  bounds[0] = 0;
  bounds[count] = end_us;
  for (std::size_t k = 1; k < count; ++k) bounds[k] = carry_time_us(path, phones[k].start_us);
  for (std::size_t k = 1; k < count; ++k) bounds[k] = std::max(bounds[k], bounds[k - 1] + kMinPhoneUs);
  for (std::size_t k = count; k-- > 1;) bounds[k] = std::min(bounds[k], bounds[k + 1] - kMinPhoneUs);
  open_closures_after_pauses(bounds, phones);
  start_at_speech_after_pauses(bounds, phones, recording_quiet);
  open_closures_after_nasals(bounds, phones, bursts_us, path);
  start_voiced_bilabials_at_closures(bounds, phones, recording);
  return bounds;
}

std::vector<RefinedBoundary> refine_lip_phones(const PcmAudio& audio, LabeledUtterance& phones,
                                               const ClosureRefinerOptions& options) {
  LabeledUtterance stand_in = phones;
  for (std::size_t i = 0; i < stand_in.intervals.size(); ++i) {
    stand_in.intervals[i].label = lip_phone_for_refiner(phones.intervals[i].label);
    stand_in.intervals[i].line = static_cast<int>(i);
  }
  std::vector<RefinedBoundary> refined = refine_closures(audio, stand_in, options);
  std::vector<LabeledInterval> intervals;
  intervals.reserve(stand_in.intervals.size());
  for (const LabeledInterval& interval : stand_in.intervals) {
    const LabeledInterval& phone = phones.intervals[static_cast<std::size_t>(interval.line)];
    intervals.push_back({phone.label, interval.start_us, interval.end_us, phone.line});
  }
  phones.intervals = std::move(intervals);
  return refined;
}

}  // namespace detail
}  // namespace lipsync::speech
