// espeak-ng's voices: the voice files of espeak-ng-data as `espeak-ng --voices` lists them, which
// voice a name chooses, and whether it speaks English. Read from the data path alone, without
// espeak_Initialize, so both the asking process and a synthesis worker can use it.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/speech/synthesizer.hpp"

namespace lipsync::speech::detail {

/// espeak-ng's voice list, read once per process. Not locked: the callers of the public
/// list_voices() and phone_set_for_voice() hold voice_list_mutex; a worker has one thread.
const std::vector<Voice>& voice_list();

/// The voice espeak-ng would choose for `name` (as its own command line does: a voice name or file,
/// else a language), or nullptr. A variant after '+' ("en+f3") does not change the language.
const Voice* find_voice(std::string_view name);

/// The voices closest to `name` (a word of their name, the start of a language or file, a typo of
/// at most two letters), closest first, at most `limit`.
std::vector<const Voice*> close_voices(std::string_view name, std::size_t limit);

/// "unknown voice 'X'; close matches: fr (French (France)), ...; 'lipsync voices' lists ...".
std::string unknown_voice_text(std::string_view name);

/// Whether the voice `voice_name` chooses has an English language first ("en", "en-…"): such a
/// voice keeps espeak-ng's mnemonics (the 'espeak' phone set), every other speaks IPA.
bool speaks_english(std::string_view voice_name);

}  // namespace lipsync::speech::detail
