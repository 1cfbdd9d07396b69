// The classes of espeak-ng's phoneme labels (espeak_labels.hpp), read from how a label begins.
#include "espeak_labels.hpp"

#include <algorithm>
#include <cctype>
#include <iterator>
#include <string_view>

namespace lipsync::speech::detail {

bool starts_with_closure(const std::string& label) {
  if (label.empty()) return false;
  if (std::string_view("pbtdkgcq").find(label.front()) != std::string_view::npos) return true;
  return label.starts_with("ɟ") || label.starts_with("ʈ") || label.starts_with("ɖ");
}

std::string lip_phone_for_refiner(const std::string& label) {
  if (label.empty()) return label;
  if (label.starts_with("β")) return "B";
  const char first = label.front();
  if (first != 'p' && first != 'b' && first != 'm' && first != 'f' && first != 'v') {
    return starts_with_closure(label) ? "T" : "X";  // the refiner finds a /p b/'s closure after a stop apart
  }
  if (label.size() > 1 && std::isalpha(static_cast<unsigned char>(label[1]))) return "X";  // "pf", "ts"…
  return std::string(1, static_cast<char>(std::toupper(static_cast<unsigned char>(first))));
}

bool is_nasal(const std::string& label) {
  if (label.empty()) return false;
  if (label.front() == 'm' || label.front() == 'n' || label.front() == 'N') return true;
  return label.starts_with("ŋ") || label.starts_with("ɲ") || label.starts_with("ɳ") || label.starts_with("ɱ");
}

bool is_voiced_closure(const std::string& label) {
  if (is_nasal(label)) return true;
  if (label.empty()) return false;
  if (std::string_view("bdg").find(label.front()) != std::string_view::npos) return true;
  return label.starts_with("ɡ") || label.starts_with("ɟ") || label.starts_with("ɖ") || label.starts_with("ɢ");
}

bool is_vowel(const std::string& label) {
  if (label.empty()) return false;
  if (std::string_view("aeiouy@3VIUOAE").find(label.front()) != std::string_view::npos) return true;
  for (const std::string_view vowel :
       {"ɑ", "ɐ", "ɒ", "æ", "ɛ", "ɜ", "ə", "ɘ", "ɵ", "ɞ", "ɤ", "ɨ", "ɪ", "ʊ", "ʌ", "ɔ", "ø", "œ", "ɯ", "ʉ", "ʏ", "ɶ"}) {
    if (label.starts_with(vowel)) return true;
  }
  return false;
}

bool is_fricative_or_affricate(const std::string& label) {
  if (label.empty()) return false;
  static constexpr std::string_view kAscii = "fvszhxTDSZC";  // T D S Z C: the mnemonics' θ ð ʃ ʒ ç
  static constexpr std::string_view kIpa[] = {"θ", "ð", "ʃ", "ʒ", "ç", "ʝ", "ɣ", "χ", "ʁ", "ħ", "ʕ",
                                              "ɸ", "β", "ʂ", "ʐ", "ɕ", "ʑ", "ɬ", "ɮ", "ʦ", "ʧ", "ʤ"};
  const auto starts_fricative = [&](std::string_view rest) {
    if (!rest.empty() && kAscii.find(rest.front()) != std::string_view::npos) return true;
    return std::any_of(std::begin(kIpa), std::end(kIpa), [&](std::string_view f) { return rest.starts_with(f); });
  };
  if (starts_fricative(label)) return true;
  // An affricate: a stop followed by a fricative ("ts", "tʃ", "dʑ", "dZ", "pf").
  return starts_with_closure(label) && label.size() > 1 && starts_fricative(std::string_view(label).substr(1));
}

bool may_be_squeezed_into_closure(const std::string& label) {
  return !label.empty() && !is_nasal(label) && !is_fricative_or_affricate(label);
}

}  // namespace lipsync::speech::detail
