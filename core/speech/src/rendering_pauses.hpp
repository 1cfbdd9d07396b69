// Pauses, in the recording and in espeak-ng's rendering of its transcript (dtw_aligner.hpp). A
// speaker pauses where espeak-ng runs on, and espeak-ng pauses between some words where a speaker
// runs on; either way the warp gives the pause to whatever the other audio says there and carries the
// boundaries after it into the pause. So after a first warp missing_pauses finds the recording's
// pauses that the rendering lacks, extra_pauses the rendering's that the recording lacks (both
// declared in dtw_aligner.hpp), and with_pauses puts the first into espeak-ng's audio as silence and
// cuts the second from it, for the warp to be done again. The frames at pause level (pause_frames)
// are also where the warp's long runs are free and where a voiced sound after a pause starts.
#pragma once

#include <utility>
#include <vector>

#include "lipsync/speech/dtw_aligner.hpp"

namespace lipsync::speech::detail {

/// The frames quieter than the loudest by more than kSpeechRangeDb (35 dB).
std::vector<bool> pause_frames(const FeatureFrames& frames);

/// `audio` (kFeatureRateHz) and `phones` (espeak-ng's, stops from their bursts) with each pause of
/// `pauses` put in as silence at the start of its phone in `moved` (the same phones, stops from their
/// closures): a stop's closure then follows the pause, the pause's interval ends at its burst. Each of
/// `cuts` is cut from the middle of its pause in `moved`, the pause's intervals shortened.
std::pair<PcmAudio, LabeledUtterance> with_pauses(const PcmAudio& audio, const LabeledUtterance& phones,
                                                  const LabeledUtterance& moved, std::vector<MissingPause> pauses,
                                                  const std::vector<ExtraPause>& cuts);

}  // namespace lipsync::speech::detail
