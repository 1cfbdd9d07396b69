// Text in: speech synthesis with espeak-ng's C library, giving the audio and the
// phonemes espeak-ng spoke, timed on that audio's own sample clock.
//
// espeak-ng reports each phoneme as an espeakEVENT_PHONEME event carrying its
// name (`id.string`: for English voices its mnemonic, the espeak phone set of
// data/phonesets/espeak.json; for every other voice its IPA symbol, the ipa
// phone set) and the sample at which it starts; a phoneme ends where the next one starts, the
// last one where the audio ends. So the phoneme times are the synthesiser's
// own, exact to the sample (45 µs at 22 050 Hz), not an estimate.
//
// espeak-ng keeps its synthesis state (voice, parameters, output buffers, the
// callback, and wave-generator state that carries from one utterance to the next)
// in process-wide globals and is not re-entrant. synthesize() therefore runs each
// synthesis in a process of its own (the running program started again, with
// exec: safe in a multi-threaded server), where espeak-ng starts fresh (so the
// result depends on the text and options alone, not on what the process spoke
// before), and holds one global mutex for a whole synthesis: calls from several
// threads are safe but run one at a time.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/setting_ranges.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync::speech {

/// espeak-ng's speaking rate in words per minute: its range and default, stated once for the
/// synthesiser's check, `lipsync say/speak --rate` (help and check) and Speak's words_per_minute.
inline constexpr IntSetting kWordsPerMinuteSetting = {80, 450, 175};

struct SynthesisOptions {
  std::string voice = "en-us";  ///< an espeak-ng voice: list_voices(), `lipsync voices`
  int words_per_minute = static_cast<int>(kWordsPerMinuteSetting.default_value);  ///< kWordsPerMinuteSetting
};

struct Synthesis {
  PcmAudio audio;             ///< mono 16-bit at espeak-ng's rate (22 050 Hz)
  LabeledUtterance phonemes;  ///< phone_set_for_voice(voice); covers [0, audio end] without gaps
  /// Where each word of the text (as white space separates them) starts, µs: the start of the first
  /// phoneme espeak-ng spoke for it (from its word events); -1 for a word it spoke nothing for.
  std::vector<std::int64_t> word_starts_us;
  /// What the user should know about espeak-ng's reading, one sentence each, naming the words:
  /// words read by another language's rules, spelled out letter by letter, or (Hebrew) without vowels.
  std::vector<std::string> notes;
};

/// One voice file of espeak-ng-data (`lipsync voices` lists them).
struct Voice {
  std::string name;                    ///< e.g. "German"
  std::string identifier;              ///< the file, e.g. "gmw/de"; a valid SynthesisOptions::voice
  std::vector<std::string> languages;  ///< e.g. {"de"}; the first is the voice's own
};

/// Every voice espeak-ng has (read from its data, without initialising it: safe in any process).
std::vector<Voice> list_voices();

/// The name `--voice` (SynthesisOptions::voice) takes for `voice`: its file name, lowered ("fr").
std::string voice_option_name(const Voice& voice);

/// Why espeak-ng knows no voice `voice` (by name, file or language, a variant after '+' aside),
/// naming the closest voices ("unknown voice 'Frnch'; close matches: fr (French (France)), ..."),
/// or nullopt for a voice it knows.
std::optional<std::string> unknown_voice_error(std::string_view voice);

/// The phone set of the phonemes synthesize() reports for `voice`: "espeak" (mnemonics) for an
/// English voice, "ipa" for every other (and for a name espeak-ng does not know).
std::string phone_set_for_voice(std::string_view voice);

/// Speaks `text` (UTF-8) in a fresh espeak-ng (a process of its own). Mandarin characters in the
/// cmn voice are read as Mandarin (its pinyin variant), U+02BC between letters as an apostrophe.
/// Throws InputError (source "espeak-ng") for an empty text, an unknown voice (naming close
/// matches), a text espeak-ng would read as nonsense (the names of characters it cannot read,
/// naming the words) or a failed synthesis;
/// std::runtime_error when the process cannot be started, dies, or has not answered
/// after 30 s plus 10 ms per byte of text (it is then killed).
Synthesis synthesize(std::string_view text, const SynthesisOptions& options = {});

}  // namespace lipsync::speech
