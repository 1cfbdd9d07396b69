// Lip closures found in the sound itself: the aligner's /p b m f v/ boundaries moved
// to the acoustic events they stand for.
//
// PocketSphinx places boundaries on a 10 ms grid with a model that knows nothing of
// what a closure sounds like, yet a lip closure is the clearest event in speech:
// when the lips close for /p b/ the formant energy falls away within a few
// milliseconds (only a voicing bar below 400 Hz survives in /b/) and comes back with
// the burst; an /m/'s nasal murmur keeps its low resonance but loses most of the
// energy above it; /f v/ lose the formants to weak frication. All five therefore
// show as a step down and a step up of the short-time energy in the formant band
// (400 to 3500 Hz, two second-order filters), which is all this unit looks at.
//
// For each such phone it measures, at every millisecond within `search_us` of the
// aligner's start, the drop D(t) = level[t-10 ms, t) - level[t, t+10 ms) in dB,
// and within `search_us` of its end the rise R(t) = level[t, t+10 ms) -
// level[t-10 ms, t). The boundary moves to the largest step, less a small penalty
// per ms of distance from the aligner's boundary, when that step reaches
// `min_step_db`: the step in dB is the move's confidence. A release goes to the
// steepest rise; a closure to where its fall begins (walking back from the steepest
// fall while D(t) stays at least `closure_onset_fraction` of it) less
// `closure_lead_us`, as the level starts to drop while the lips close. An /m/ whose
// formant band falls by less than `min_step_db` (the vowel's energy partly carried
// into the murmur) is looked for in the nasal contrast too, the formant band's level
// less the level below 400 Hz, which the murmur raises: where that falls by
// `min_step_db` or more and the formant band falls there too, the closure is at its
// steepest fall. Where no step is that clear the aligner's boundary stays. An /m/ before a /p b/
// has no release (the lips stay closed into the stop): its end is left to the stop's closure,
// where the murmur falls to the stop's silence. Pauses next to lip phones get four rules:
// a /p b/ after a pause of at most `longest_closure_pause_us` had that silence as its
// closure (the recogniser hears a silent closure as a pause and puts the stop at its
// burst), so it takes the pause over and its start is refined from where the pause
// started; when the phone before that pause is itself a stop, the pause holds that
// stop's closure and release too (so it may last twice as long), and the /p b/ starts at
// the pause's last fall of the level instead, or, with neither a fall nor that stop's
// release heard, halfway between that stop's start and the /p b/'s burst; a pause of at most
// `longest_closure_pause_us` after a /p b/ (and before a phone) is the rest of its closure, heard as
// silence up to the burst, so the stop takes it over too (`pause_after_stop_is_its_closure`); and an /m f v/ after a
// pause, with no closing movement to hear, starts at the level's steepest rise (its sound's onset). Neighbouring phones
// keep at least `min_phone_us` and their order; the utterance still tiles the same span. Pure computation on the
// samples: the same audio and phones give the same result.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "lipsync/speech/audio.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync::speech {

struct ClosureRefinerOptions {
  /// How far from the aligner's boundary a step is looked for, µs.
  std::int64_t search_us = 30'000;
  /// The smallest step of the formant band's level that moves a boundary, dB.
  double min_step_db = 10.0;
  /// How much a step loses per ms of distance from the aligner's boundary, dB/ms.
  double distance_penalty_db_per_ms = 0.3;
  /// Where the fall of the level begins, as a share of the steepest fall: walking back
  /// from the steepest fall, the closure's onset is the earliest point whose fall is
  /// still this share of it.
  double closure_onset_fraction = 0.4;
  /// How far before that onset the closure is placed, µs: the level starts to fall
  /// while the lips are still closing.
  std::int64_t closure_lead_us = 3'000;
  /// How far after the steepest rise the release is placed, µs.
  std::int64_t release_lag_us = 0;
  /// The longest pause before a /p b/ that is taken for the stop's silent closure, µs
  /// (twice this after another stop: the pause then holds both closures).
  std::int64_t longest_closure_pause_us = 160'000;
  /// Whether a pause of at most longest_closure_pause_us after a /p b/ (and before a phone) is the
  /// rest of its closure, as a recogniser hears it; off where the pauses are the phonemes of a
  /// synthesis that was carried across (dtw_refiner_options).
  bool pause_after_stop_is_its_closure = true;
  /// The shortest a phone may become, µs.
  std::int64_t min_phone_us = 10'000;
};

/// What happened to one boundary of a lip phone.
struct RefinedBoundary {
  std::size_t phone = 0;        ///< index into the utterance's intervals
  bool release = false;         ///< false: the phone's start (closure); true: its end (release)
  std::int64_t aligned_us = 0;  ///< where the aligner put it
  std::int64_t refined_us = 0;  ///< where it is now (aligned_us when kept)
  double step_db = 0;           ///< the energy step found there (the confidence); 0 when none
  bool moved = false;           ///< step_db reached min_step_db and the boundary moved
};

/// True for the ARPAbet phones whose boundaries refine_closures moves: P B M F V
/// (upper or lower case, stress digits ignored).
bool is_lip_phone(std::string_view arpabet);

/// Moves the boundaries of the lip phones of `phones` (ARPAbet, tiling the audio)
/// to the energy steps of `audio` near them; returns one entry per boundary looked at.
/// Audio below 8 kHz (whose band would not fit) is left alone: nothing is returned.
std::vector<RefinedBoundary> refine_closures(const PcmAudio& audio, LabeledUtterance& phones,
                                             const ClosureRefinerOptions& options = {});

/// The formant band's level (400 to 3500 Hz) of `audio` in dBFS over windows of
/// `window_us` every `hop_us`, both in whole milliseconds (rounded down, at least 1 ms;
/// the first window starts at 0; none below 8 kHz): for plots and tests.
std::vector<double> formant_band_levels_db(const PcmAudio& audio, std::int64_t window_us, std::int64_t hop_us);

/// The level below 400 Hz (a /b/'s voicing bar, a nasal's murmur) of `audio` in dBFS, windowed as
/// formant_band_levels_db.
std::vector<double> low_band_levels_db(const PcmAudio& audio, std::int64_t window_us, std::int64_t hop_us);

}  // namespace lipsync::speech
