// What espeak-ng is given and what its reading means (espeak_readings.hpp).
#include "espeak_readings.hpp"

#include <algorithm>
#include <cstdint>
#include <map>

namespace lipsync::speech::detail {
namespace {

constexpr char32_t kModifierApostrophe = 0x02BC;

/// One code point of UTF-8 `text` at byte `i`: its value and its byte length (a broken byte is
/// taken as itself, one byte long, as espeak-ng takes it).
std::pair<char32_t, std::size_t> decode(std::string_view text, std::size_t i) {
  const auto lead = static_cast<unsigned char>(text[i]);
  const std::size_t length = lead < 0x80 ? 1 : lead >= 0xF0 ? 4 : lead >= 0xE0 ? 3 : lead >= 0xC0 ? 2 : 1;
  if (i + length > text.size()) return {lead, 1};
  char32_t value = length == 1 ? lead : lead & (0x3F >> (length - 1));
  for (std::size_t k = 1; k < length; ++k) value = (value << 6) | (static_cast<unsigned char>(text[i + k]) & 0x3F);
  return {value, length};
}

std::vector<std::pair<char32_t, std::string_view>> code_points(std::string_view text) {
  std::vector<std::pair<char32_t, std::string_view>> out;
  for (std::size_t i = 0; i < text.size();) {
    const auto [value, length] = decode(text, i);
    out.emplace_back(value, text.substr(i, length));
    i += length;
  }
  return out;
}

bool is_ascii_letter(char32_t c) { return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

/// Latin letters: ASCII, Latin-1's letters and Latin Extended-A/B.
bool is_latin_letter(char32_t c) { return is_ascii_letter(c) || (c >= 0xC0 && c <= 0x24F && c != 0xD7 && c != 0xF7); }

bool is_han(char32_t c) {
  return (c >= 0x3400 && c <= 0x4DBF) || (c >= 0x4E00 && c <= 0x9FFF) || (c >= 0xF900 && c <= 0xFAFF) ||
         (c >= 0x20000 && c <= 0x2FA1F);
}

/// A letter of any script, near enough for "between two letters": not ASCII's non-letters, not
/// white space or punctuation (general, CJK), not the apostrophe itself.
bool is_letter(char32_t c) {
  if (c < 0x80) return is_ascii_letter(c);
  return c != kModifierApostrophe && c != 0xA0 && !(c >= 0x2000 && c <= 0x206F) && !(c >= 0x3000 && c <= 0x303F);
}

/// Characters that join the run around them: white space, digits, punctuation.
bool is_neutral(char32_t c) { return !is_letter(c) && !is_han(c); }

/// Hebrew points and cantillation marks (niqqud, U+0591..U+05C7 less the letters' range).
bool is_hebrew_point(char32_t c) { return c >= 0x0591 && c <= 0x05C7; }

bool is_switch(std::string_view phoneme) {
  return phoneme == "_^_" || (phoneme.size() >= 3 && phoneme.front() == '(' && phoneme.back() == ')');
}

/// The language a switch names ("(en)" → "en"; the mnemonic "_^_" names none).
std::string switch_language(std::string_view phoneme) {
  return phoneme == "_^_" ? std::string() : std::string(phoneme.substr(1, phoneme.size() - 2));
}

/// Whether an IPA phoneme name is a vowel (its first code point is one of the chart's vowels).
bool is_vowel(std::string_view phoneme) {
  static constexpr std::u32string_view kVowels = U"aeiouyæɑɐɒɔəɘɛɜɞɤɨɪɯɵøœɶʉʊʌʏäëïöü";
  if (phoneme.empty()) return false;
  return kVowels.find(decode(phoneme, 0).first) != std::u32string_view::npos;
}

/// 'a', 'b' and 'c'.
std::string quoted_list(const std::vector<std::string>& words) {
  std::string out;
  for (std::size_t i = 0; i < words.size(); ++i) {
    if (i > 0) out += i + 1 == words.size() ? " and " : ", ";
    out += "'" + words[i] + "'";
  }
  return out;
}

void add_once(std::vector<std::string>& words, const std::string& word) {
  if (std::find(words.begin(), words.end(), word) == words.end()) words.push_back(word);
}

/// What espeak-ng did with one word of the text.
struct WordReading {
  std::size_t position = 0;
  std::size_t length = 0;
  int events = 0;  // word events at this position: more than one when spelled out
  std::vector<std::string> phonemes;
  std::string other_language;  // the first other language a sound of the word was spoken in ("" if none)
  bool switched = false;       // a sound of the word was spoken in another language
};

}  // namespace

std::string prepare_text(std::string_view text) {
  const auto points = code_points(text);
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const bool apostrophe = points[i].first == kModifierApostrophe && i > 0 && i + 1 < points.size() &&
                            is_letter(points[i - 1].first) && is_letter(points[i + 1].first);
    out += apostrophe ? std::string_view("'") : points[i].second;
  }
  return out;
}

bool has_han(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    const auto [value, length] = decode(text, i);
    if (is_han(value)) return true;
    i += length;
  }
  return false;
}

std::vector<TextRun> split_runs(std::string_view text, const std::string& voice, const std::string& pinyin_voice) {
  if (pinyin_voice.empty() || !has_han(text)) return {{std::string(text), voice, 0}};
  const auto points = code_points(text);
  // Each code point's voice: Latin letters the given one, other letters and Han the pinyin one,
  // neutral characters that of the letter before them (before the first letter: after them).
  std::vector<const std::string*> chosen(points.size(), nullptr);
  const std::string* current = nullptr;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!is_neutral(points[i].first)) current = is_latin_letter(points[i].first) ? &voice : &pinyin_voice;
    chosen[i] = current;
  }
  const auto first_letter =
      std::find_if(chosen.begin(), chosen.end(), [](const std::string* v) { return v != nullptr; });
  const std::string* leading = first_letter == chosen.end() ? &pinyin_voice : *first_letter;
  std::replace(chosen.begin(), chosen.end(), static_cast<const std::string*>(nullptr), leading);

  std::vector<TextRun> runs;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (runs.empty() || runs.back().voice != *chosen[i]) runs.push_back({"", *chosen[i], i});
    runs.back().text += points[i].second;
  }
  return runs;
}

ReadingVerdict judge_reading(std::string_view text, const std::vector<SpokenWord>& words, std::string_view voice_name,
                             std::string_view language) {
  const auto points = code_points(text);
  const bool english = language == "en" || language.starts_with("en-");
  const std::string own = std::string(language.substr(0, language.find('-')));

  // The words in text order, each with every phoneme spoken for it and whether a sound of it was
  // spoken in another language: a switch holds until the switch back, which may come words later
  // ("like tea" in the cmn voice: "(en)" before "like", "(cmn)" after "tea"). The mnemonic "_^_"
  // of English voices names no language: each one toggles.
  std::map<std::size_t, WordReading> readings;
  std::string current;  // the language spoken in now, "" for the voice's own
  for (const SpokenWord& word : words) {
    WordReading& reading = readings[word.position];
    reading.position = word.position;
    reading.length = std::max(reading.length, word.length);
    ++reading.events;
    reading.phonemes.insert(reading.phonemes.end(), word.phonemes.begin(), word.phonemes.end());
    for (const std::string& phoneme : word.phonemes) {
      if (is_switch(phoneme)) {
        const std::string switched_to = switch_language(phoneme);
        if (phoneme == "_^_") {
          current = current.empty() ? "another language" : "";
        } else {
          current = switched_to == own || switched_to == language ? "" : switched_to;
        }
      } else if (!phoneme.empty() && !current.empty()) {
        reading.switched = true;
        if (reading.other_language.empty() && current != "another language") reading.other_language = current;
      }
    }
  }

  std::vector<std::string> unreadable, foreign, spelled, vowelless, foreign_languages, unreadable_languages;
  bool han = false, pointed = false;
  std::string vowelless_example;
  for (const auto& [position, reading] : readings) {
    if (position == 0 || position > points.size()) continue;
    const std::size_t end = std::min(points.size(), position - 1 + std::max<std::size_t>(reading.length, 1));
    std::string word;
    bool ascii = true;
    for (std::size_t i = position - 1; i < end; ++i) {
      word += points[i].second;
      ascii = ascii && points[i].first < 0x80;
      han = han || is_han(points[i].first);
      pointed = pointed || is_hebrew_point(points[i].first);
    }
    const std::string& other = reading.other_language;
    const bool switched = reading.switched;
    const bool spelled_out = reading.events > 1;
    if (spelled_out && !ascii && (switched || english)) {
      add_once(unreadable, word);
      if (!other.empty()) add_once(unreadable_languages, other);
    } else if (switched) {
      add_once(foreign, word);
      if (!other.empty()) add_once(foreign_languages, other);
    } else if (spelled_out) {
      add_once(spelled, word);
    } else if (own == "he") {
      std::size_t sounds = 0;
      bool vowel = false;
      std::string ipa;
      for (const std::string& phoneme : reading.phonemes) {
        if (phoneme.empty()) continue;
        ++sounds;
        vowel = vowel || is_vowel(phoneme);
        ipa += phoneme;
      }
      if (sounds >= 2 && !vowel) {
        add_once(vowelless, word);
        if (vowelless_example.empty()) vowelless_example = "/" + ipa + "/";
      }
    }
  }

  ReadingVerdict verdict;
  const auto languages_text = [](const std::vector<std::string>& languages) {
    std::string out;
    for (const std::string& code : languages) out += (out.empty() ? "" : ", ") + code;
    return out;
  };
  if (!unreadable.empty()) {
    verdict.refusal = "voice '" + std::string(voice_name) + "' cannot read " + quoted_list(unreadable) +
                      ": espeak-ng would speak the names of the characters" +
                      (unreadable_languages.empty() ? "" : " (in " + languages_text(unreadable_languages) + ")") +
                      " instead of the words";
    if (han && own == "ja") verdict.refusal += "; write Japanese in kana (espeak-ng 1.51 reads no kanji)";
    if (han && own != "ja") verdict.refusal += "; Chinese characters are read by --voice cmn (Mandarin) or yue";
    if (pointed) verdict.refusal += "; espeak-ng 1.51 reads Hebrew without points (niqqud) only";
    verdict.refusal += " (docs/languages.md says what works per script)";
  }
  if (!foreign.empty()) {
    verdict.notes.push_back("espeak-ng read " + quoted_list(foreign) + " by the rules of another language" +
                            (foreign_languages.empty() ? "" : " (" + languages_text(foreign_languages) + ")") +
                            ", not those of voice '" + std::string(voice_name) + "'");
  }
  if (!spelled.empty()) {
    verdict.notes.push_back("espeak-ng spelled out " + quoted_list(spelled) + " letter by letter");
  }
  if (!vowelless.empty()) {
    verdict.notes.push_back("espeak-ng read " + quoted_list(vowelless) + " without vowels (" +
                            (vowelless.size() > 1 ? "the first as " : "as ") + vowelless_example +
                            "): it knows the vowels of unpointed Hebrew only for the words in its dictionary");
  }
  return verdict;
}

}  // namespace lipsync::speech::detail
