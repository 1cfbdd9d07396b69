// How espeak-ng reads a text, and whether lipsync may let that reading pass.
//
// Before: the text espeak-ng is given. The Ukrainian (and Belarusian) apostrophe U+02BC, which
// espeak-ng 1.51 reads as the English word "ejective" and spells the whole word out around it,
// becomes the ASCII apostrophe that those voices read as the apostrophe it is. Mandarin written in
// characters goes to the cmn voice's pinyin variant: espeak-ng's cmn dictionary turns each character
// into its pinyin with a tone digit ("我" → "wo3"), and the `cmn` voice file ("latin as English",
// `dictrules 1`) then reads that pinyin by the English rules, tone digits as English numbers.
// `cmn-latn-pinyin` reads the same pinyin as Mandarin; Latin words stay with `cmn` (English).
//
// After: what espeak-ng did with each word, from its word events (text position and length) and
// the phoneme events that follow each. A word it could not read it spells out: one word event per
// character, all at the word's position. A word it reads in another language's rules carries a
// switch, the IPA phoneme "(en)" (the mnemonic "_^_" in English voices). So:
//   - spelled out, non-ASCII, and in another language (or in an English voice): espeak-ng speaks
//     the names of the characters ("Chinese letter" for a kanji, "Hebrew point" for niqqud), which
//     is nonsense as speech: refused, naming the words;
//   - read in another language, or spelled out letter by letter: a note naming the words;
//   - Hebrew: a word with no vowel among several phonemes is unpointed Hebrew outside espeak-ng's
//     small dictionary, read as its consonants alone: a note naming the words.
// All of it is pure: text and events in, text, runs and notes out.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace lipsync::speech::detail {

/// A stretch of the text that one espeak-ng voice speaks.
struct TextRun {
  std::string text;
  std::string voice;
  std::size_t first_character = 0;  ///< code points of the whole text before the run
};

/// The text as espeak-ng should be given it: U+02BC between two letters becomes "'".
std::string prepare_text(std::string_view text);

/// Whether `text` holds a Han character (CJK unified ideographs, their extensions, compatibility).
bool has_han(std::string_view text);

/// The runs `text` is spoken in with `voice`. With `pinyin_voice` set (the chosen voice is the
/// cmn file that reads Latin as English) and Han characters in the text: runs of Latin letters
/// stay with `voice`, everything else goes to `pinyin_voice`. Otherwise one run.
std::vector<TextRun> split_runs(std::string_view text, const std::string& voice, const std::string& pinyin_voice);

/// One espeak-ng word event and the phonemes that followed it, in order.
struct SpokenWord {
  std::size_t position = 0;  ///< 1-based code point index of the word in the whole text
  std::size_t length = 0;    ///< in code points
  std::vector<std::string> phonemes;
};

/// What espeak-ng's reading means for the user.
struct ReadingVerdict {
  std::vector<std::string> notes;  ///< one sentence each, naming the words
  std::string refusal;             ///< non-empty: the reading is nonsense; why, naming the words
};

/// Judges the reading of `text` (as given to espeak-ng) by `voice_name` (as the user named it),
/// whose own language is `language` ("ja", "en-us"; English ones speak mnemonics).
ReadingVerdict judge_reading(std::string_view text, const std::vector<SpokenWord>& words, std::string_view voice_name,
                             std::string_view language);

}  // namespace lipsync::speech::detail
