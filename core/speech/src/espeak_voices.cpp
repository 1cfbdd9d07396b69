// espeak-ng's voices (espeak_voices.hpp), and the public list_voices() and phone_set_for_voice().
//
// Which phone set a voice's phonemes come in depends on its language: espeak-ng names the
// phonemes of its events with the mnemonics of each language's phoneme table (`Y:`, `z2`, ...),
// which differ between tables, or, initialised with espeakINITIALIZE_PHONEME_IPA, with their IPA
// symbols, one vocabulary for all languages. English voices keep the mnemonics and the 'espeak'
// phone set (so English speech renders as it always did); every other voice speaks IPA, rendered
// through the 'ipa' phone set. Which one a voice is comes from its language in espeak-ng's voice
// list, read before initialisation (espeak_ListVoices needs only the data path), so the worker
// can initialise with the right flag (docs/languages.md).
#include "espeak_voices.hpp"

#include <espeak-ng/espeak_ng.h>
#include <espeak-ng/speak_lib.h>

#include <algorithm>
#include <cstring>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

namespace lipsync::speech {

std::string voice_option_name(const Voice& voice) {
  std::string identifier = voice.identifier.substr(voice.identifier.rfind('/') + 1);
  for (char& c : identifier) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return identifier;
}

namespace detail {
namespace {

std::string lower_ascii(std::string_view text) {
  std::string out(text);
  for (char& c : out) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return out;
}

}  // namespace

const std::vector<Voice>& voice_list() {
  static const std::vector<Voice> kVoices = [] {
    std::vector<Voice> out;
    espeak_ng_InitializePath(nullptr);
    const espeak_VOICE** listed = espeak_ListVoices(nullptr);
    for (std::size_t i = 0; listed != nullptr && listed[i] != nullptr; ++i) {
      Voice voice;
      voice.name = listed[i]->name != nullptr ? listed[i]->name : "";
      voice.identifier = listed[i]->identifier != nullptr ? listed[i]->identifier : "";
      // languages: a priority byte, a language name and its zero, ..., and a final zero.
      for (const char* language = listed[i]->languages; language != nullptr && language[0] != 0;
           language += std::strlen(language + 1) + 2) {
        voice.languages.emplace_back(language + 1);
      }
      out.push_back(std::move(voice));
    }
    return out;
  }();
  return kVoices;
}

const Voice* find_voice(std::string_view name) {
  const std::string wanted = lower_ascii(name.substr(0, name.find('+')));
  std::string spaced = wanted;  // "English_(America)", as espeak-ng --voices writes the name
  std::replace(spaced.begin(), spaced.end(), '_', ' ');
  const std::vector<Voice>& voices = voice_list();
  for (const Voice& voice : voices) {
    const std::string voice_name = lower_ascii(voice.name);
    const std::string identifier = lower_ascii(voice.identifier);
    const std::string file = identifier.substr(identifier.rfind('/') + 1);
    if (voice_name == wanted || voice_name == spaced || identifier == wanted || file == wanted) return &voice;
  }
  for (const Voice& voice : voices) {
    for (const std::string& language : voice.languages) {
      if (lower_ascii(language) == wanted) return &voice;
    }
  }
  return nullptr;
}

namespace {

/// Levenshtein distance of two short ASCII-lowered strings.
std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

/// How close voice `voice` is to the lowered name `wanted`: 0 is a name that starts with it or a
/// word of the name that is it ("french" → "French (France)"), 1 a language or file that starts with
/// it ("fr" → "fr-be"), 2 + the edit distance for a typo (at most 2); nullopt: not close.
std::optional<std::size_t> closeness(const Voice& voice, const std::string& wanted) {
  if (wanted.empty()) return std::nullopt;
  const std::string name = lower_ascii(voice.name);
  std::string words = name;
  for (char& c : words) {
    if (c == '(' || c == ')' || c == ',' || c == '_') c = ' ';
  }
  if (name.starts_with(wanted) || (" " + words + " ").find(" " + wanted + " ") != std::string::npos) return 0;
  std::vector<std::string> codes = {voice_option_name(voice)};
  for (const std::string& language : voice.languages) codes.push_back(lower_ascii(language));
  for (const std::string& code : codes) {
    if (code.starts_with(wanted) || wanted.starts_with(code + "-") || wanted.starts_with(code + "_")) return 1;
  }
  std::size_t best = edit_distance(wanted, name);
  for (const std::string& code : codes) best = std::min(best, edit_distance(wanted, code));
  for (std::size_t start = 0; start < words.size();) {  // each word of the name ("frnch" → "french")
    const std::size_t end = std::min(words.find(' ', start), words.size());
    if (end > start) best = std::min(best, edit_distance(wanted, words.substr(start, end - start)));
    start = end + 1;
  }
  if (best <= 2 && best < wanted.size()) return 2 + best;
  return std::nullopt;
}

}  // namespace

std::vector<const Voice*> close_voices(std::string_view name, std::size_t limit) {
  const std::string wanted = lower_ascii(name.substr(0, name.find('+')));
  std::vector<std::pair<std::size_t, const Voice*>> scored;
  for (const Voice& voice : voice_list()) {
    if (const auto score = closeness(voice, wanted)) scored.emplace_back(*score, &voice);
  }
  // Closest first; among equals the shorter name first ("fr" before "fr-be").
  std::stable_sort(scored.begin(), scored.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first
                              : voice_option_name(*a.second).size() < voice_option_name(*b.second).size();
  });
  std::vector<const Voice*> out;
  for (std::size_t i = 0; i < scored.size() && i < limit; ++i) out.push_back(scored[i].second);
  return out;
}

std::string unknown_voice_text(std::string_view name) {
  std::string text = "unknown voice '" + std::string(name) + "'";
  const std::vector<const Voice*> close = close_voices(name, 6);
  if (!close.empty()) {
    text += "; close matches:";
    for (std::size_t i = 0; i < close.size(); ++i) {
      text += (i == 0 ? " " : ", ") + voice_option_name(*close[i]) + " (" + close[i]->name + ")";
    }
  }
  return text + "; 'lipsync voices' lists every voice and the name --voice takes";
}

bool speaks_english(std::string_view voice_name) {
  const Voice* voice = find_voice(voice_name);
  if (voice == nullptr || voice->languages.empty()) return false;
  const std::string language = lower_ascii(voice->languages.front());
  return language == "en" || language.starts_with("en-");
}

}  // namespace detail

namespace {
std::mutex voice_list_mutex;
}  // namespace

std::vector<Voice> list_voices() {
  const std::lock_guard lock(voice_list_mutex);
  return detail::voice_list();
}

std::string phone_set_for_voice(std::string_view voice) {
  const std::lock_guard lock(voice_list_mutex);
  return detail::speaks_english(voice) ? "espeak" : "ipa";
}

std::optional<std::string> unknown_voice_error(std::string_view voice) {
  const std::lock_guard lock(voice_list_mutex);
  if (detail::find_voice(voice) != nullptr) return std::nullopt;
  return detail::unknown_voice_text(voice);
}

}  // namespace lipsync::speech
