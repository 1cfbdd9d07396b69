// The rules that place espeak-ng's phone boundaries in the recording where the warp alone does not
// (dtw_aligner.hpp). Before the warp, each stop of the rendering starts at its closure rather than at
// its burst, where espeak-ng reports it. After it, the boundaries carried across are kept in order and
// apart, and then: a stop after a pause or a nasal, whose closure shows no fall of the level in either
// audio, has its closure opened before its burst; a nasal or voiced stop after a pause starts where
// the recording leaves pause level; a voiced /b/ inside a voiced closure of the recording starts where
// that closure begins (start_voiced_bilabials_at_closures); an /m/ carried into the vowel before it
// starts at its murmur (start_bilabial_nasals_at_murmur; both declared in dtw_aligner.hpp, to be
// tested alone). Last, the closure refiner moves the lip phones' boundaries to the recording's energy
// steps. Each rule's constants stand above it, with the measurements they were chosen on.
#pragma once

#include <cstdint>
#include <vector>

#include "lipsync/speech/dtw_aligner.hpp"

namespace lipsync::speech::detail {

/// espeak-ng starts a stop's phoneme event at its burst, the closure's silence still counted in
/// the phoneme before. Each stop's start moves back to the steepest fall of the formant band's
/// level within kStopClosureSearchUs before it (the closure), when the fall is clear, so that
/// what is carried to the recording is where the stop begins, as in a recording's labels. Returns
/// every phoneme's start before the move (a stop's burst).
std::vector<std::int64_t> move_stop_starts_to_closures(const PcmAudio& audio, LabeledUtterance& phones);

/// The boundaries of `phones` (espeak-ng's, stops from their closures) carried across the warp to a
/// recording of `end_us`, in order and at least kMinPhoneUs (1 ms) apart, with the closures of stops after a
/// pause or a nasal opened, sounds after a pause started at the recording's speech (`recording_quiet`:
/// its frames at pause level) and voiced /b/ started at their closures: bounds[k] is the start of
/// phones[k], bounds[size] the end.
std::vector<std::int64_t> carried_bounds(const WarpPath& path, const std::vector<LabeledInterval>& phones,
                                         const std::vector<std::int64_t>& bursts_us, std::int64_t end_us,
                                         const std::vector<bool>& recording_quiet, const PcmAudio& recording);

/// Runs the closure refiner on `phones` (labels of espeak-ng) through their ARPAbet stand-ins. The
/// refiner may give a short pause before a /p b/ to the stop (its closure, heard as silence) and drop
/// it: each stand-in carries the index of its phone in `line`, so the labels follow their intervals.
std::vector<RefinedBoundary> refine_lip_phones(const PcmAudio& audio, LabeledUtterance& phones,
                                               const ClosureRefinerOptions& options);

}  // namespace lipsync::speech::detail
