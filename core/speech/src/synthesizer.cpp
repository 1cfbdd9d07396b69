// Text in (lipsync/speech/synthesizer.hpp): synthesize() checks the request, then has a synthesis
// worker speak it, one at a time. The parts, each in a file named after its job:
//
//   espeak_voices.cpp      espeak-ng's voice list: which voice a name chooses, which phone set
//                          it speaks (list_voices(), phone_set_for_voice());
//   espeak_synthesis.cpp   one synthesis with espeak-ng's library, its phoneme events turned into
//                          intervals that tile the audio (run only in a worker);
//   synthesis_wire.cpp     the request and the answer as bytes between the two processes;
//   synthesis_worker.cpp   the worker process: why there is one per synthesis, how it is started,
//                          fed, read with a deadline, and what it does before main.
#include "lipsync/speech/synthesizer.hpp"

#include <mutex>
#include <string>

#include "espeak_synthesis.hpp"
#include "lipsync/error.hpp"
#include "synthesis_worker.hpp"

namespace lipsync::speech {
namespace {

// One synthesis at a time (one worker process at a time).
std::mutex espeak_mutex;

}  // namespace

Synthesis synthesize(std::string_view text, const SynthesisOptions& options) {
  const std::string source(detail::kEspeakSource);
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) throw InputError(source, 0, "the text is empty");
  if (options.words_per_minute < kWordsPerMinuteSetting.min || options.words_per_minute > kWordsPerMinuteSetting.max) {
    throw InputError(source, 0,
                     out_of_range_text("speaking rate (words per minute)", std::to_string(options.words_per_minute),
                                       range_text(kWordsPerMinuteSetting)));
  }
  const std::lock_guard lock(espeak_mutex);
  return detail::synthesize_in_worker(text, options);
}

}  // namespace lipsync::speech
