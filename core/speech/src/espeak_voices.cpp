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
#include <string>

namespace lipsync::speech {
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

}  // namespace lipsync::speech
