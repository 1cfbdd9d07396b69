// The synthesis worker: a process of its own for each synthesis, in which espeak-ng starts fresh.
#pragma once

#include <string_view>

#include "lipsync/speech/synthesizer.hpp"

namespace lipsync::speech::detail {

/// Starts this program again as a synthesis worker, hands it the request and returns its result.
/// Throws what the worker's synthesis threw (InputError), or std::runtime_error when the process
/// cannot be started, dies, or has not answered by its deadline (it is then killed). One at a
/// time: the caller holds a lock.
Synthesis synthesize_in_worker(std::string_view text, const SynthesisOptions& options);

}  // namespace lipsync::speech::detail
