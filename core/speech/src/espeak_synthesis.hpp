// One synthesis with espeak-ng's C library in this process: the audio and the phonemes it spoke,
// from its phoneme events. Only a synthesis worker calls it (synthesis_worker.cpp): espeak-ng keeps
// its state in process-wide globals, once initialised per process.
#pragma once

#include <string_view>

#include "lipsync/speech/synthesizer.hpp"

namespace lipsync::speech::detail {

/// The source name of espeak-ng's phonemes and of every error of a synthesis.
inline constexpr std::string_view kEspeakSource = "espeak-ng";

/// Speaks `text` in this process's espeak-ng (initialised on the first call, for IPA names unless
/// the voice speaks English). Throws InputError (source kEspeakSource) when espeak-ng cannot be
/// initialised, the voice is unknown, the synthesis fails or gives no phonemes.
Synthesis synthesize_with_espeak(std::string_view text, const SynthesisOptions& options);

}  // namespace lipsync::speech::detail
