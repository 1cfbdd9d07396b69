// Lip boundaries moved to the energy steps of the formant band
// (lipsync/speech/closure_refiner.hpp).
#include "lipsync/speech/closure_refiner.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <numbers>
#include <string>

namespace lipsync::speech {
namespace {

constexpr double kLowEdgeHz = 400;              // below: /b/'s voicing bar and /m/'s nasal resonance
constexpr double kHighEdgeHz = 3500;            // above: frication and burst noise
constexpr std::int64_t kStepWindowUs = 10'000;  // each side of a candidate step
constexpr std::int64_t kCandidateStepUs = 1'000;
constexpr double kFloorDb = -100;    // digital silence
constexpr int kLowestRateHz = 8000;  // the band needs its 3500 Hz below Nyquist

// A second-order section, RBJ audio-EQ cookbook form, Q = 1/sqrt(2) (Butterworth).
struct Biquad {
  double b0, b1, b2, a1, a2;
  double x1 = 0, x2 = 0, y1 = 0, y2 = 0;

  static Biquad make(double hz, double rate_hz, bool high_pass) {
    const double w = 2 * std::numbers::pi * hz / rate_hz;
    const double alpha = std::sin(w) / (2 * std::numbers::sqrt2 / 2);
    const double c = std::cos(w);
    const double a0 = 1 + alpha;
    const double k = high_pass ? (1 + c) / 2 : (1 - c) / 2;
    const double b1 = high_pass ? -(1 + c) : 1 - c;
    return Biquad{k / a0, b1 / a0, k / a0, -2 * c / a0, (1 - alpha) / a0};
  }
  double step(double x) {
    const double y = b0 * x + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2;
    x2 = x1, x1 = x, y2 = y1, y1 = y;
    return y;
  }
};

// The bands looked at: the formants (400 to 3500 Hz, a high-pass and a low-pass
// section) and the nasal murmur's resonance below them (below 400 Hz, two low-pass
// sections).
enum class Band { kFormants, kNasal };

// A band's energy in every millisecond [k ms, k+1 ms) of the audio (summed
// per millisecond, so a quiet millisecond late in a long recording keeps its
// precision), with running sums over the milliseconds: the level of any whole-ms
// span in O(1).
class BandEnergy {
 public:
  BandEnergy(const PcmAudio& audio, Band band) {
    const int rate_hz = audio.sample_rate_hz;
    const bool formants = band == Band::kFormants;
    Biquad high = Biquad::make(kLowEdgeHz, rate_hz, formants);
    Biquad low = Biquad::make(formants ? std::min(kHighEdgeHz, 0.45 * rate_hz) : kLowEdgeHz, rate_hz, false);
    const auto frames = static_cast<std::int64_t>(audio.samples.size()) * 1000 / rate_hz;
    prefix_.assign(static_cast<std::size_t>(frames) + 1, 0.0L);
    samples_per_frame_.assign(static_cast<std::size_t>(frames), 0);
    std::int64_t i = 0;
    for (std::int64_t k = 0; k < frames; ++k) {
      const std::int64_t end = (k + 1) * rate_hz / 1000;
      double sum = 0;
      for (; i < end; ++i) {
        const double y = low.step(high.step(audio.samples[static_cast<std::size_t>(i)] / 32768.0));
        sum += y * y;
      }
      prefix_[static_cast<std::size_t>(k) + 1] = prefix_[static_cast<std::size_t>(k)] + sum;
      samples_per_frame_[static_cast<std::size_t>(k)] = static_cast<int>(end - k * rate_hz / 1000);
    }
  }
  std::int64_t frames() const { return static_cast<std::int64_t>(samples_per_frame_.size()); }
  // Level of the frames [a, b) in dBFS (a full-scale sine in the band is -3 dB).
  double level_db(std::int64_t a, std::int64_t b) const {
    a = std::clamp<std::int64_t>(a, 0, frames());
    b = std::clamp<std::int64_t>(b, 0, frames());
    if (b <= a) return kFloorDb;
    const auto sum = static_cast<double>(prefix_[static_cast<std::size_t>(b)] - prefix_[static_cast<std::size_t>(a)]);
    const double mean = sum / double(sample_count(a, b));
    return mean > 0 ? std::max(kFloorDb, 10 * std::log10(mean)) : kFloorDb;
  }

 private:
  std::int64_t sample_count(std::int64_t a, std::int64_t b) const {
    std::int64_t n = 0;
    for (std::int64_t k = a; k < b; ++k) n += samples_per_frame_[static_cast<std::size_t>(k)];
    return std::max<std::int64_t>(n, 1);
  }
  std::vector<long double> prefix_;
  std::vector<int> samples_per_frame_;
};

// The formant band's level of every millisecond [k ms, k+1 ms), floored
// kRangeDb below the loudest, and running sums of it: the mean level of any span of
// milliseconds in O(1). A step is measured between the mean levels (in dB) of the
// 10 ms before and after a candidate time: for an ideal step of H dB that is a
// triangle peaking at H exactly at the step (the pitch periods in 1 ms frames
// average out over ten of them), so the step is located to the millisecond even
// where one side is digital silence.
constexpr double kRangeDb = 60;

class LevelTrack {
 public:
  explicit LevelTrack(const BandEnergy& energy) {
    std::vector<double> levels(static_cast<std::size_t>(energy.frames()));
    for (std::int64_t k = 0; k < energy.frames(); ++k) levels[static_cast<std::size_t>(k)] = energy.level_db(k, k + 1);
    const double loudest = levels.empty() ? kFloorDb : *std::max_element(levels.begin(), levels.end());
    prefix_.reserve(levels.size() + 1);
    prefix_.push_back(0);
    for (const double level : levels) prefix_.push_back(prefix_.back() + std::max(level, loudest - kRangeDb));
  }
  // The difference of two tracks' levels, millisecond by millisecond.
  LevelTrack(const LevelTrack& minuend, const LevelTrack& subtrahend) : prefix_(minuend.prefix_) {
    for (std::size_t k = 0; k < prefix_.size(); ++k) prefix_[k] -= subtrahend.prefix_[k];
  }
  std::int64_t frames() const { return static_cast<std::int64_t>(prefix_.size()) - 1; }
  // The fall of the level at t: the mean of the 10 ms before less that of the 10 ms after, dB.
  double fall_db(std::int64_t t_us) const {
    constexpr std::int64_t kSide = kStepWindowUs / kCandidateStepUs;
    const std::int64_t k = t_us / kCandidateStepUs;
    if (k < kSide || k + kSide > frames()) return 0;
    return mean_db(k - kSide, k) - mean_db(k, k + kSide);
  }
  // Mean level of frames [a, b), dB.
  double mean_db(std::int64_t a, std::int64_t b) const {
    return (prefix_[static_cast<std::size_t>(b)] - prefix_[static_cast<std::size_t>(a)]) / double(b - a);
  }

 private:
  std::vector<double> prefix_;
};

// The formant band's level, and the nasal contrast: the formant band's level less
// the level below 400 Hz. An /m/ closing after a vowel can keep much of the vowel's
// energy in the formant band (espeak-ng's "lemons": a fall of 7.7 dB) while its murmur
// raises the level below it, so its closure is a larger step of the contrast (12 dB
// there) than of the formant band alone.
struct Levels {
  LevelTrack formants;
  LevelTrack nasal_contrast;
};

struct Step {
  std::int64_t at_us = 0;
  double db = 0;
};

// The largest step (down when `falling`) within [from_us, to_us], scored against its
// distance from `aligned_us`.
Step best_step(const LevelTrack& levels, std::int64_t aligned_us, std::int64_t from_us, std::int64_t to_us,
               bool falling, const ClosureRefinerOptions& options) {
  constexpr std::int64_t kSide = kStepWindowUs / kCandidateStepUs;
  const std::int64_t first = std::max((from_us + kCandidateStepUs - 1) / kCandidateStepUs, kSide);
  const std::int64_t last = std::min(to_us / kCandidateStepUs, levels.frames() - kSide);
  Step best;
  double best_score = -1e300;
  for (std::int64_t k = first; k <= last; ++k) {
    const double before = levels.mean_db(k - kSide, k);
    const double after = levels.mean_db(k, k + kSide);
    const double step = falling ? before - after : after - before;
    const std::int64_t t = k * kCandidateStepUs;
    const double score = step - options.distance_penalty_db_per_ms * double(std::abs(t - aligned_us)) / 1000.0;
    if (score > best_score) best_score = score, best = {t, step};
  }
  return best;
}

std::string upper_letters(std::string_view arpabet) {
  std::string phone;
  for (const char c : arpabet) {
    if (std::isalpha(static_cast<unsigned char>(c)))
      phone += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  }
  return phone;
}

bool is_bilabial_nasal(std::string_view arpabet) { return upper_letters(arpabet) == "M"; }

// /m f v/: phones whose sound (murmur, frication) is heard from their first moment.
bool starts_with_sound(std::string_view arpabet) {
  const std::string phone = upper_letters(arpabet);
  return phone == "M" || phone == "F" || phone == "V";
}

bool is_oral_bilabial_stop(std::string_view arpabet) {
  const std::string phone = upper_letters(arpabet);
  return phone == "P" || phone == "B";
}

// An /m/ before a /p b/ (Italian "compra", Finnish "puistoon pelaamaan" said [m p]): the lips stay
// closed from the nasal into the stop's closure, so there is no release between them; the murmur's
// end is the stop's start, found as its closure.
bool closes_into_stop(std::string_view nasal, std::string_view next) {
  return is_bilabial_nasal(nasal) && is_oral_bilabial_stop(next);
}

bool is_stop(std::string_view arpabet) {
  const std::string phone = upper_letters(arpabet);
  return phone == "P" || phone == "B" || phone == "T" || phone == "D" || phone == "K" || phone == "G" ||
         phone == "CH" || phone == "JH";
}

// A short pause before a /p b/: the stop's closure, heard as silence. After another stop
// (`before`) the pause can hold that stop's closure and release as well as the /p b/'s
// closure, so it may last twice as long: espeak-ng's "catch pink", a 190 ms pause over the
// /tʃ/'s frication and the /p/'s closure.
bool is_stop_closure_pause(const LabeledInterval& before, const LabeledInterval& pause, const LabeledInterval& stop,
                           const ClosureRefinerOptions& options) {
  const std::int64_t longest =
      is_stop(before.label) ? 2 * options.longest_closure_pause_us : options.longest_closure_pause_us;
  return pause.label.empty() && is_oral_bilabial_stop(stop.label) && pause.end_us - pause.start_us <= longest;
}

// A short pause after a /p b/, before a phone: the rest of the stop's closure, heard as silence.
// The recogniser labels the stop by its closing transition and the silence after it as a pause, up
// to the burst (espeak-ng's "Wipe the", "sharp reef", "pup gnawed": a 30 ms /p/, then 100 to 120 ms of
// pause). The mirror of the pause before a /p b/.
bool holds_rest_of_closure(const std::vector<LabeledInterval>& intervals, std::size_t i,
                           const ClosureRefinerOptions& options) {
  if (!options.pause_after_stop_is_its_closure || !is_oral_bilabial_stop(intervals[i].label) ||
      i + 2 >= intervals.size()) {
    return false;
  }
  const LabeledInterval& pause = intervals[i + 1];
  return pause.label.empty() && !intervals[i + 2].label.empty() &&
         pause.end_us - pause.start_us <= options.longest_closure_pause_us;
}

// The latest step (down when `falling`) of at least `min_db` within [from_us, to_us]:
// the last one found walking back from to_us, at its peak.
Step latest_step(const LevelTrack& levels, std::int64_t from_us, std::int64_t to_us, bool falling, double min_db) {
  constexpr std::int64_t kSide = kStepWindowUs / kCandidateStepUs;
  const std::int64_t first = std::max((from_us + kCandidateStepUs - 1) / kCandidateStepUs, kSide);
  const std::int64_t last = std::min(to_us / kCandidateStepUs, levels.frames() - kSide);
  const auto step_at = [&](std::int64_t k) {
    const double before = levels.mean_db(k - kSide, k), after = levels.mean_db(k, k + kSide);
    return falling ? before - after : after - before;
  };
  std::int64_t k = last;
  while (k >= first && step_at(k) < min_db) --k;
  if (k < first) return {};
  while (k > first && step_at(k - 1) >= step_at(k)) --k;
  return {k * kCandidateStepUs, step_at(k)};
}

// Where the fall found at `step` begins: the earliest time, walking back from it
// without a gap, whose fall is still closure_onset_fraction of the step's. A closing
// gesture lowers the level over 10 to 30 ms before the steepest fall (more slowly in
// diphone speech than in a stop's digital silence), so the onset, not the steepest
// point, is where the lips start to seal.
std::int64_t fall_onset_us(const LevelTrack& levels, const Step& step, std::int64_t from_us,
                           const ClosureRefinerOptions& options) {
  constexpr std::int64_t kSide = kStepWindowUs / kCandidateStepUs;
  const auto fall = [&](std::int64_t k) { return levels.mean_db(k - kSide, k) - levels.mean_db(k, k + kSide); };
  const std::int64_t first = std::max((from_us + kCandidateStepUs - 1) / kCandidateStepUs, kSide);
  std::int64_t k = step.at_us / kCandidateStepUs;
  while (k - 1 >= first && fall(k - 1) >= options.closure_onset_fraction * step.db) --k;
  return k * kCandidateStepUs;
}

// Moves the start of the lip phone intervals[i] (i > 0): after a pause to the rise of
// its sound (/m f v/), otherwise to the closure, where the formant band's level falls.
void refine_start(const Levels& levels, std::vector<LabeledInterval>& intervals, std::size_t i,
                  const ClosureRefinerOptions& options, std::vector<RefinedBoundary>& refined) {
  LabeledInterval& previous = intervals[i - 1];
  LabeledInterval& phone = intervals[i];
  const std::int64_t aligned = phone.start_us;
  const std::int64_t from = std::max(aligned - options.search_us, previous.start_us + options.min_phone_us);
  const std::int64_t to = std::min(aligned + options.search_us, phone.end_us - options.min_phone_us);
  if (previous.label.empty() && starts_with_sound(phone.label)) {
    // After a pause there is no closing movement to hear: an /m f v/ starts where its
    // sound does, at the level's steepest rise.
    const Step step = best_step(levels.formants, aligned, from, to, false, options);
    const bool moved = step.db >= options.min_step_db;
    if (moved) previous.end_us = phone.start_us = step.at_us;
    refined.push_back({i, false, aligned, phone.start_us, std::max(0.0, step.db), moved});
    return;
  }
  Step step = best_step(levels.formants, aligned, from, to, true, options);
  std::int64_t at = fall_onset_us(levels.formants, step, from, options) - options.closure_lead_us;
  if (is_bilabial_nasal(phone.label) && step.db < options.min_step_db) {
    // An /m/ whose closing the formant band hardly hears: its murmur's onset, where the
    // nasal contrast falls while the formant band falls too (from a fricative both
    // rise, the low band more, and the contrast falls with no closing). The murmur
    // starts at once, so the closure is at the contrast's steepest fall, with no lead.
    const Step nasal = best_step(levels.nasal_contrast, aligned, from, to, true, options);
    if (nasal.db >= options.min_step_db && levels.formants.fall_db(nasal.at_us) > 0) {
      step = nasal;
      at = nasal.at_us;
    }
  }
  at = std::max(at, previous.start_us + options.min_phone_us);
  const bool moved = step.db >= options.min_step_db && at <= phone.end_us - options.min_phone_us;
  if (moved) previous.end_us = phone.start_us = at;
  refined.push_back({i, false, aligned, phone.start_us, std::max(0.0, step.db), moved});
}

// Moves the end of the lip phone intervals[i] (not the last) to its release, where the level
// rises again.
void refine_release(const Levels& levels, std::vector<LabeledInterval>& intervals, std::size_t i,
                    const ClosureRefinerOptions& options, std::vector<RefinedBoundary>& refined) {
  LabeledInterval& next = intervals[i + 1];
  const std::int64_t aligned = intervals[i].end_us;
  const Step step = best_step(
      levels.formants, aligned, std::max(aligned - options.search_us, intervals[i].start_us + options.min_phone_us),
      std::min(aligned + options.search_us, next.end_us - options.min_phone_us), false, options);
  const std::int64_t at = std::min(step.at_us + options.release_lag_us, next.end_us - options.min_phone_us);
  const bool moved = step.db >= options.min_step_db && at >= intervals[i].start_us + options.min_phone_us;
  if (moved) intervals[i].end_us = next.start_us = at;
  refined.push_back({i, true, aligned, intervals[i].end_us, std::max(0.0, step.db), moved});
}

// A /p b/ after another stop (/t p/, /k b/), with or without a pause the recogniser heard
// between them: the stretch before its burst holds the first stop's closure and release, then
// the /p b/'s own closure. A stop the recogniser hears where none was said holds the /p/ too:
// Festival's "fine punch", heard without a transcript as "find punch", 36 ms late (its middle
// still shown closed). Where the /p b/ starts, case by case:
enum class StartAfterStop {
  // A pause between the two stops holds both closures: the /p b/'s starts at the pause's last
  // fall of the level.
  kPauseLastFall,
  // A pause, and neither a fall nor the first stop's release heard: one silence holds both
  // closures, from the first stop's start to the /p b/'s burst, and where the lips close in it
  // is not heard. Each closure takes half of it. Festival's "get back": 3 ms late, where its burst
  // is 53 ms late.
  kPauseMidpoint,
  // No pause, the first stop's release (a rise of the level) heard before the last fall before
  // the /p b/'s burst: as across a pause, the /p b/ starts at that fall. Russian "ест пирог": the
  // warp puts the /pʲ/ 84 ms early, inside the /t/'s closure before its burst; this case starts it
  // 8 ms early.
  kReleaseLastFall,
  // No pause and no release heard: the one silence holds both closures and where the lips close
  // in it is not heard, so the boundary stays. After the warp the English "big brown" /g b/ stays
  // 15 ms early; refined as any other /b/, it would take the /g/'s closure, 45 ms early. The
  // boundary stays too wherever no case above applies: no last fall heard, or one that would
  // leave the /p b/ shorter than min_phone_us, and no midpoint to take.
  kStays,
};

// Which case a /p b/ after a stop is, from what is heard before its burst.
StartAfterStop start_after_stop(bool pause_between, bool last_fall_fits, bool release_heard, bool midpoint_fits) {
  if (pause_between) {
    if (last_fall_fits) return StartAfterStop::kPauseLastFall;
    if (!release_heard && midpoint_fits) return StartAfterStop::kPauseMidpoint;
    return StartAfterStop::kStays;
  }
  return last_fall_fits && release_heard ? StartAfterStop::kReleaseLastFall : StartAfterStop::kStays;
}

// Moves the start of the /p b/ intervals[i] after another stop: intervals[i - 1] is that stop,
// or, when `pause_between`, the pause after it (and the stop is intervals[i - 2]).
void refine_start_after_stop(const Levels& levels, std::vector<LabeledInterval>& intervals, std::size_t i,
                             bool pause_between, const ClosureRefinerOptions& options,
                             std::vector<RefinedBoundary>& refined) {
  LabeledInterval& previous = intervals[i - 1];
  LabeledInterval& phone = intervals[i];
  const LabeledInterval& first_stop = pause_between ? intervals[i - 2] : previous;
  const std::int64_t aligned = phone.start_us;
  const std::int64_t from = previous.start_us + options.min_phone_us;
  // The last fall before the burst: the recogniser puts the /p b/ at its burst after a pause;
  // with none between the warp may put it early, inside the closure ("ест пирог"), so the fall is
  // looked for up to min_phone_us before its end.
  const std::int64_t last_fall_by = pause_between ? aligned : phone.end_us - options.min_phone_us;
  const Step last_fall = latest_step(levels.formants, from, last_fall_by, true, options.min_step_db);
  const std::int64_t last_fall_at =
      std::max(fall_onset_us(levels.formants, last_fall, from, options) - options.closure_lead_us, from);
  // The first stop's release: a rise at least 10 ms before the burst across a pause, before the
  // last fall with none.
  const std::int64_t release_before = pause_between ? aligned : last_fall.at_us;
  const Step release =
      best_step(levels.formants, release_before, first_stop.start_us + options.min_phone_us,
                release_before - kStepWindowUs, false, ClosureRefinerOptions{.distance_penalty_db_per_ms = 0});
  const std::int64_t middle = (first_stop.start_us + aligned) / 2;
  const StartAfterStop start =
      start_after_stop(pause_between, last_fall.db > 0 && last_fall_at <= phone.end_us - options.min_phone_us,
                       release.db >= options.min_step_db, middle >= from);
  switch (start) {
    case StartAfterStop::kPauseLastFall:
    case StartAfterStop::kReleaseLastFall:
      previous.end_us = phone.start_us = last_fall_at;
      break;
    case StartAfterStop::kPauseMidpoint:
      previous.end_us = phone.start_us = middle;
      break;
    case StartAfterStop::kStays:
      break;
  }
  refined.push_back({i, false, aligned, phone.start_us, last_fall.db, start != StartAfterStop::kStays});
}

// A /p b/ right after a stop other than /p b/, no pause between (/t p/, /k b/).
bool follows_other_stop(const std::vector<LabeledInterval>& intervals, std::size_t i) {
  return i > 0 && is_stop(intervals[i - 1].label) && !is_oral_bilabial_stop(intervals[i - 1].label) &&
         is_oral_bilabial_stop(intervals[i].label);
}

}  // namespace

bool is_lip_phone(std::string_view arpabet) {
  const std::string phone = upper_letters(arpabet);
  return phone == "P" || phone == "B" || phone == "M" || phone == "F" || phone == "V";
}

std::vector<RefinedBoundary> refine_closures(const PcmAudio& audio, LabeledUtterance& phones,
                                             const ClosureRefinerOptions& options) {
  std::vector<RefinedBoundary> refined;
  if (audio.samples.empty() || audio.sample_rate_hz < kLowestRateHz) return refined;
  LevelTrack formants{BandEnergy(audio, Band::kFormants)};
  LevelTrack nasal_contrast(formants, LevelTrack{BandEnergy(audio, Band::kNasal)});
  const Levels levels{std::move(formants), std::move(nasal_contrast)};
  std::vector<LabeledInterval>& intervals = phones.intervals;
  for (std::size_t i = 0; i < intervals.size(); ++i) {
    if (!is_lip_phone(intervals[i].label)) continue;
    if (holds_rest_of_closure(intervals, i, options)) {
      // The stop takes the pause over: its release is then refined from the pause's end, and its
      // closure looked for in its whole span.
      intervals[i].end_us = intervals[i + 1].end_us;
      intervals.erase(intervals.begin() + static_cast<std::ptrdiff_t>(i + 1));
    }
    const bool after_pause = i > 1 && is_stop_closure_pause(intervals[i - 2], intervals[i - 1], intervals[i], options);
    const bool pause_between_stops = after_pause && is_stop(intervals[i - 2].label);
    if (pause_between_stops || follows_other_stop(intervals, i)) {
      refine_start_after_stop(levels, intervals, i, pause_between_stops, options, refined);
    } else {
      if (after_pause && !intervals[i - 2].label.empty()) {
        // The recogniser heard the stop's silent closure as a pause: the closure starts
        // where that silence does, so the stop takes it over and its start is refined
        // from there.
        intervals[i].start_us = intervals[i - 1].start_us;
        intervals.erase(intervals.begin() + static_cast<std::ptrdiff_t>(i - 1));
        --i;
      }
      if (i > 0) refine_start(levels, intervals, i, options, refined);
    }
    // An /m/ closing into a /p b/ has no release: the lips stay closed into the stop.
    if (i + 1 < intervals.size() && !closes_into_stop(intervals[i].label, intervals[i + 1].label))
      refine_release(levels, intervals, i, options, refined);
  }
  return refined;
}

namespace {

std::vector<double> band_levels_db(const PcmAudio& audio, Band band, std::int64_t window_us, std::int64_t hop_us) {
  std::vector<double> levels;
  if (audio.samples.empty() || audio.sample_rate_hz < kLowestRateHz) return levels;
  const BandEnergy energy(audio, band);
  const std::int64_t window = std::max<std::int64_t>(1, window_us / 1000),
                     hop = std::max<std::int64_t>(1, hop_us / 1000);
  for (std::int64_t k = 0; k + window <= energy.frames(); k += hop) levels.push_back(energy.level_db(k, k + window));
  return levels;
}

}  // namespace

std::vector<double> formant_band_levels_db(const PcmAudio& audio, std::int64_t window_us, std::int64_t hop_us) {
  return band_levels_db(audio, Band::kFormants, window_us, hop_us);
}

std::vector<double> low_band_levels_db(const PcmAudio& audio, std::int64_t window_us, std::int64_t hop_us) {
  return band_levels_db(audio, Band::kNasal, window_us, hop_us);
}

}  // namespace lipsync::speech
