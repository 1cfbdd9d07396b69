// What both aligners check of a recording before they start (PocketSphinx's, aligner.cpp, and the
// warp against espeak-ng's rendering, dtw_aligner.cpp), stated once: the file is not longer than
// the aligner accepts, its sample rate carries speech, it is not too short, and it is not silent.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "lipsync/speech/audio.hpp"

namespace lipsync::speech::detail {

/// Level of each 20 ms window of `audio`, dBFS (-200 for digital silence).
std::vector<double> window_levels_dbfs(const PcmAudio& audio);

/// The window levels of `audio` once it passed the checks; throws InputError naming `source`
/// when it is longer than `max_duration_s`, its sample rate is under 8000 Hz (`purpose` says what
/// needs more: "speech recognition", "alignment"), it lasts under 0.1 s, or its loudest 20 ms is
/// under -50 dBFS.
std::vector<double> check_alignable_audio(const PcmAudio& audio, const std::string& source, double max_duration_s,
                                          std::string_view purpose);

}  // namespace lipsync::speech::detail
