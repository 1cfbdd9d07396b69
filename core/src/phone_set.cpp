// Phone-set tables (schema: docs/phone-sets.md): input label → model phoneme.
//
// A label is normalised before lookup: the set's ignored code points (stress
// digits, IPA stress marks) are removed and, for case-insensitive sets, ASCII
// letters are lower-cased. Table keys go through the same normalisation, so a
// table cannot hold two keys that would collide.
#include "lipsync/phone_set.hpp"

#include <algorithm>
#include <nlohmann/json.hpp>

#include "embedded_data.hpp"
#include "lipsync/error.hpp"
#include "lipsync/model.hpp"

namespace lipsync {
namespace {

using nlohmann::json;

/// The length in bytes of the UTF-8 code point that starts at text[i] (by its
/// lead byte; a sequence cut short by the end of the text ends there).
std::size_t code_point_length(std::string_view text, std::size_t i) {
  const auto lead = static_cast<unsigned char>(text[i]);
  std::size_t length = 1;
  if (lead >= 0xF0)
    length = 4;
  else if (lead >= 0xE0)
    length = 3;
  else if (lead >= 0xC0)
    length = 2;
  return std::min(length, text.size() - i);
}

/// Splits UTF-8 text into code points (each as its byte sequence).
std::vector<std::string> code_points(std::string_view text) {
  std::vector<std::string> points;
  for (std::size_t i = 0; i < text.size();) {
    const std::size_t length = code_point_length(text, i);
    points.emplace_back(text.substr(i, length));
    i += length;
  }
  return points;
}

// The order in which `auto` detection tries the built-in sets: the most common
// aligner output first; sets that share labels map them identically.
constexpr std::string_view kDetectionOrder[] = {"arpabet", "radio", "timit", "ipa", "espeak", "sampa"};

}  // namespace

PhoneSet PhoneSet::from_json(std::string_view json_text, std::string_view source_name, const ArticulationModel& model) {
  const std::string source(source_name);
  json root;
  try {
    root = json::parse(json_text.begin(), json_text.end());
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number that overflows
    throw InputError(source, 0, std::string("not valid JSON: ") + e.what());
  }
  const auto fail = [&](const std::string& message) { throw InputError(source, 0, message); };
  if (!root.is_object()) fail("a phone set must be a JSON object");
  for (const auto& [key, value] : root.items()) {
    static const std::vector<std::string> kKnown = {"format",
                                                    "version",
                                                    "name",
                                                    "description",
                                                    "case_sensitive",
                                                    "ignore_characters",
                                                    "phones",
                                                    "fallback_ignore_characters",
                                                    "fallback_split",
                                                    "fallback_skip",
                                                    "phoneme_substitutes"};
    if (std::find(kKnown.begin(), kKnown.end(), key) == kKnown.end()) fail("unknown field '" + key + "'");
  }
  // Types are checked before values are read: json::value() throws a type_error, not an
  // InputError, for a field of another type ("format": true).
  if (!root.contains("format") || root["format"] != "lipsync-phone-set") {
    fail("field 'format' must be \"lipsync-phone-set\"");
  }
  if (!root.contains("version") || root["version"] != 1) fail("field 'version' must be 1");
  if (!root.contains("name") || !root["name"].is_string()) fail("field 'name' must be a string");
  if (!root.contains("phones") || !root["phones"].is_object()) fail("field 'phones' must be an object");

  PhoneSet set;
  set.name_ = root["name"].get<std::string>();
  if (root.contains("description")) {
    if (!root["description"].is_string()) fail("field 'description' must be a string");
    set.description_ = root["description"].get<std::string>();
  }
  if (root.contains("case_sensitive")) {
    if (!root["case_sensitive"].is_boolean()) fail("field 'case_sensitive' must be true or false");
    set.case_sensitive_ = root["case_sensitive"].get<bool>();
  }
  if (root.contains("ignore_characters")) {
    if (!root["ignore_characters"].is_string()) fail("field 'ignore_characters' must be a string");
    set.ignored_ = code_points(root["ignore_characters"].get<std::string>());
    for (const std::string& point : set.ignored_) {
      if (point.size() == 1 && static_cast<unsigned char>(point[0]) < set.ignored_ascii_.size()) {
        set.ignored_ascii_[static_cast<unsigned char>(point[0])] = true;
      }
    }
  }
  if (root.contains("fallback_ignore_characters")) {
    if (!root["fallback_ignore_characters"].is_string()) fail("field 'fallback_ignore_characters' must be a string");
    set.fallback_ignored_ = code_points(root["fallback_ignore_characters"].get<std::string>());
  }
  if (root.contains("fallback_split")) {
    if (!root["fallback_split"].is_boolean()) fail("field 'fallback_split' must be true or false");
    set.fallback_split_ = root["fallback_split"].get<bool>();
  }
  if (root.contains("fallback_skip")) {
    if (!root["fallback_skip"].is_string()) fail("field 'fallback_skip' must be a string");
    for (const std::string& point : code_points(root["fallback_skip"].get<std::string>())) {
      set.fallback_skip_.push_back(set.normalise(point));
    }
  }
  // A phoneme the model lacks may have a substitute (the ipa set's ipa_ phonemes have English ones,
  // for models made before they existed).
  std::unordered_map<std::string, std::string> substitutes;
  if (root.contains("phoneme_substitutes")) {
    if (!root["phoneme_substitutes"].is_object()) fail("field 'phoneme_substitutes' must be an object");
    for (const auto& [phoneme, substitute] : root["phoneme_substitutes"].items()) {
      if (!substitute.is_string()) fail("phoneme_substitutes '" + phoneme + "': the substitute must be a string");
      substitutes.emplace(phoneme, substitute.get<std::string>());
    }
  }
  set.silence_phoneme_ = model.silence_phoneme();
  for (const PhonemeSpec& spec : model.phonemes())
    set.vowel_phoneme_.push_back(spec.phoneme_class == PhonemeClass::vowel);
  for (const auto& [label, target] : root["phones"].items()) {
    if (!target.is_string()) fail("phones '" + label + "': the model phoneme must be a string");
    auto phoneme = model.find_phoneme(target.get<std::string>());
    if (const auto substitute = substitutes.find(target.get<std::string>());
        !phoneme && substitute != substitutes.end()) {
      phoneme = model.find_phoneme(substitute->second);
    }
    if (!phoneme) {
      fail("phones '" + label + "': maps to '" + target.get<std::string>() + "', which model '" + model.name() +
           "' does not have");
    }
    const std::string key = set.normalise(label);
    if (key.empty()) fail("phones '" + label + "': the label is empty after normalisation");
    if (!set.phoneme_by_label_.emplace(key, *phoneme).second) {
      fail("phones '" + label + "': duplicates another label after normalisation ('" + key + "')");
    }
    set.longest_key_bytes_ = std::max(set.longest_key_bytes_, key.size());
  }
  return set;
}

std::vector<std::string> PhoneSet::builtin_names() { return {std::begin(kDetectionOrder), std::end(kDetectionOrder)}; }

std::vector<PhoneSet> PhoneSet::builtin_all(const ArticulationModel& model) {
  std::vector<PhoneSet> sets;
  for (std::string_view name : kDetectionOrder) {
    if (auto set = builtin(name, model)) sets.push_back(std::move(*set));
  }
  return sets;
}

std::optional<PhoneSet> PhoneSet::builtin(std::string_view name, const ArticulationModel& model) {
  for (const auto& file : embedded::phone_set_files()) {
    if (file.name == name) {
      return from_json(file.text, "built-in phone set '" + std::string(name) + "'", model);
    }
  }
  return std::nullopt;
}

std::string PhoneSet::normalise(std::string_view label) const {
  // Called for every phoneme a client streams: no allocation beyond the result
  // (which short labels keep in the string itself).
  std::string out;
  out.reserve(label.size());
  for (std::size_t i = 0; i < label.size();) {
    const auto byte = static_cast<unsigned char>(label[i]);
    if (byte < ignored_ascii_.size()) {
      // ASCII (nearly every label): a table lookup instead of a search through ignored_.
      ++i;
      if (ignored_ascii_[byte]) continue;
      const bool fold = !case_sensitive_ && byte >= 'A' && byte <= 'Z';
      out.push_back(static_cast<char>(fold ? byte - 'A' + 'a' : byte));
      continue;
    }
    const std::string_view point = label.substr(i, code_point_length(label, i));
    i += point.size();
    if (std::find(ignored_.begin(), ignored_.end(), point) == ignored_.end()) out += point;
  }
  return out;
}

namespace {

/// Whether a label holds a tie bar (U+0361 above, U+035C below: "t͡s"), which makes one phone of
/// its symbols.
bool has_tie_bar(std::string_view label) {
  return label.find("\xCD\xA1") != std::string_view::npos || label.find("\xCD\x9C") != std::string_view::npos;
}

}  // namespace

std::optional<int> PhoneSet::lookup(std::string_view label) const {
  if (label.empty()) return silence_phoneme_;
  std::string key = normalise(label);
  const auto it = phoneme_by_label_.find(key);
  if (it != phoneme_by_label_.end()) return it->second;
  if (fallback_ignored_.empty() && !fallback_split_) return std::nullopt;
  return fallback_lookup(key, has_tie_bar(label));
}

std::string PhoneSet::fallback_key(const std::string& normalised) const {
  std::string key;
  for (std::size_t i = 0; i < normalised.size();) {
    const std::string_view point = std::string_view(normalised).substr(i, code_point_length(normalised, i));
    i += point.size();
    if (std::find(fallback_ignored_.begin(), fallback_ignored_.end(), point) == fallback_ignored_.end()) key += point;
  }
  return key;
}

std::optional<std::vector<std::pair<std::string, int>>> PhoneSet::split(const std::string& key) const {
  // Split into the table's labels, longest first at each position; every byte must be covered.
  std::vector<std::pair<std::string, int>> pieces;
  for (std::size_t i = 0; i < key.size();) {
    std::size_t length = std::min(longest_key_bytes_, key.size() - i);
    std::unordered_map<std::string, int>::const_iterator found = phoneme_by_label_.end();
    for (; length > 0; --length) {
      // Only whole code points: the next byte must not be a UTF-8 continuation byte.
      if (i + length < key.size() && (static_cast<unsigned char>(key[i + length]) & 0xC0) == 0x80) continue;
      found = phoneme_by_label_.find(key.substr(i, length));
      if (found != phoneme_by_label_.end()) break;
    }
    if (length == 0) return std::nullopt;
    pieces.emplace_back(found->first, found->second);
    i += length;
  }
  return pieces;
}

bool PhoneSet::is_one_phone(const std::vector<std::pair<std::string, int>>& pieces, bool tied) const {
  if (tied) return true;
  std::size_t vowels = 0, others = 0;
  for (const auto& [piece, phoneme] : pieces) {
    if (pieces.size() > 1 && std::find(fallback_skip_.begin(), fallback_skip_.end(), piece) != fallback_skip_.end()) {
      continue;  // a glide or glottal onset beside the phone
    }
    const bool vowel =
        static_cast<std::size_t>(phoneme) < vowel_phoneme_.size() && vowel_phoneme_[static_cast<std::size_t>(phoneme)];
    ++(vowel ? vowels : others);
  }
  if (vowels + others <= 1) return true;
  // Consonants alone: two are an affricate (pɸ, tʃʲ); more are several phones (qqzz). A split with a
  // vowel is one: a diphthong (eu), or one of espeak-ng's own names for an r-coloured vowel (ər)
  // or a final (Cantonese oenɡ).
  return vowels > 0 || others <= 2;
}

std::optional<int> PhoneSet::fallback_lookup(const std::string& normalised, bool tied) const {
  // Only labels the table lacks come here (rare), so plain strings and searches do.
  const std::string key = fallback_key(normalised);
  if (key.empty()) return std::nullopt;
  if (const auto it = phoneme_by_label_.find(key); it != phoneme_by_label_.end()) return it->second;
  if (!fallback_split_) return std::nullopt;
  const auto pieces = split(key);
  if (!pieces || !is_one_phone(*pieces, tied)) return std::nullopt;
  // The phoneme of the first piece that is not a glide or glottal onset, else of the first.
  for (const auto& [piece, phoneme] : *pieces) {
    if (std::find(fallback_skip_.begin(), fallback_skip_.end(), piece) == fallback_skip_.end()) return phoneme;
  }
  return pieces->front().second;
}

std::optional<std::string> PhoneSet::several_phones(std::string_view label) const {
  if (label.empty() || !fallback_split_ || lookup(label)) return std::nullopt;
  const std::string key = fallback_key(normalise(label));
  const auto pieces = key.empty() ? std::nullopt : split(key);
  if (!pieces || pieces->size() < 2) return std::nullopt;
  // At most eight pieces: the error that quotes them stays short, whatever the label's length.
  constexpr std::size_t kMostShown = 8;
  std::string out;
  for (std::size_t i = 0; i < pieces->size() && i < kMostShown; ++i)
    out += (out.empty() ? "" : " ") + (*pieces)[i].first;
  if (pieces->size() > kMostShown) out += " … (" + std::to_string(pieces->size()) + " in all)";
  return out;
}

const PhoneSet& detect_phone_set(const std::vector<PhoneSet>& candidates, const std::vector<std::string_view>& labels) {
  const PhoneSet* best = &candidates.front();
  std::size_t best_unknown = labels.size() + 1;
  for (const PhoneSet& set : candidates) {
    std::size_t unknown = 0;
    for (std::string_view label : labels) {
      if (!set.lookup(label)) ++unknown;
    }
    if (unknown == 0) return set;
    if (unknown < best_unknown) {
      best = &set;
      best_unknown = unknown;
    }
  }
  return *best;
}

}  // namespace lipsync
