// Audio in: timed phonemes from recorded speech with PocketSphinx (Debian's
// 5prealpha library and its en-us model from pocketsphinx-en-us), the recogniser
// Rhubarb Lip Sync is built on.
//
// With a transcript the audio is force-aligned: each word is looked up in the
// CMU pronouncing dictionary shipped with the model (every listed pronunciation
// is an alternative), and a JSGF grammar accepts exactly those words in order,
// with optional pauses between them. The grammar's "words" are single phones
// (one dictionary entry per phone and transcript word, `aa_3` is /AA/ of word 3),
// so the recogniser's word segmentation is the phone alignment and each phone
// still knows its word. Without a transcript the model's English language model
// (en-us.lm.bin) recognises words, and those words are force-aligned as if they were
// the transcript, when they fit the audio closely (at most 10 % of its loud windows
// left in pauses; a note names them): a word knows which phones follow which, so a
// /b/ the phones alone would take for /d/ comes out right whenever its word does.
// Where the words do not fit (a voice far from the model's, as espeak-ng's formant
// synthesis is) they are listened for once more over a faint white noise floor (the
// model knows no digital silence), and kept when those fit; where neither fits the
// phones are recognised one by one, over the same floor, with the phonetic language model
// (en-us-phone.lm.bin, PocketSphinx's "allphone" search). Either way the result
// is ARPAbet at the recogniser's 10 ms frame step.
//
// After decoding, the boundaries of /p b m f v/ move to the energy steps of the signal
// (closure_refiner.hpp): the recogniser's grid is 10 ms and its model knows nothing of
// what a lip closure sounds like, while the closure and the release are plain to see
// in the formant band's level. Where the signal shows no clear step the recogniser's
// boundary stays.
//
// Bounds: the audio is converted to 16 kHz mono when it is not (a note says so),
// longer audio than `max_duration_s` is refused before decoding (a decode takes
// about 0.2x real time aligned, 0.3x from the words heard and up to 1.1x when the
// phone loop is needed, on one core, and its memory grows
// with its length), silence is refused before decoding, and a
// transcript the recogniser cannot fit to the audio is an error that says so.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/closure_refiner.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync::speech {

struct AlignmentOptions {
  /// Words spoken in the audio (punctuation and case ignored); none: recognise phones.
  std::optional<std::string> transcript;
  /// The acoustic model directory's parent, holding en-us/, cmudict-en-us.dict, en-us-phone.lm.bin.
  std::string model_dir = "/usr/share/pocketsphinx/model/en-us";
  /// Longest audio accepted, seconds.
  double max_duration_s = 120;
  /// Move the lip phones' boundaries to the signal's energy steps (closure_refiner.hpp).
  bool refine_closures = true;
  ClosureRefinerOptions refiner;
};

struct Alignment {
  LabeledUtterance phones;               ///< phone_set "arpabet"; "" is silence; tiles [0, audio end]
  std::vector<LabeledInterval> words;    ///< transcript words, or the words recognised (lower case); may be empty
  std::vector<std::string> notes;        ///< conversions done on the audio, for the user
  std::vector<RefinedBoundary> refined;  ///< what refine_closures did to each lip boundary
};

/// Aligns `audio` (any rate, converted to 16 kHz); `source` names it in errors.
/// Throws InputError: audio too long or silent, a word missing from the dictionary,
/// a transcript that does not fit the audio, a model that cannot be loaded.
Alignment align_speech(const PcmAudio& audio, std::string_view source, const AlignmentOptions& options = {});

/// The transcript's words as the dictionary spells them: lower case, letters,
/// digits and apostrophes; everything else separates words.
std::vector<std::string> transcript_words(std::string_view transcript);

/// Writes `alignment` as a long-format Praat TextGrid with the tiers "words" (when
/// there are words) and "phones", from 0 to `duration_us`.
void write_textgrid(std::ostream& out, const Alignment& alignment, std::int64_t duration_us);

}  // namespace lipsync::speech
