// Phone sets: the label vocabularies of aligners and TTS front-ends (ARPAbet,
// TIMIT, Festival "radio" phones, IPA, espeak-ng, SAMPA) and their mapping to
// the model's phoneme inventory. Each mapping is a table in data
// (data/phonesets/*.json, docs/phone-sets.md), never code.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

namespace lipsync {

class ArticulationModel;

class PhoneSet {
 public:
  /// Parses a phone-set table and checks that every target it names exists in
  /// `model`. Throws InputError naming `source` and the offending label.
  static PhoneSet from_json(std::string_view json_text, std::string_view source, const ArticulationModel& model);

  /// The phone sets embedded in the binary, resolved against `model`.
  /// Throws InputError if a built-in table names a phoneme the model lacks.
  static std::vector<PhoneSet> builtin_all(const ArticulationModel& model);
  /// One built-in phone set by name; nullopt if there is none of that name.
  static std::optional<PhoneSet> builtin(std::string_view name, const ArticulationModel& model);
  /// Names of the built-in phone sets, in the order `auto` detection tries them.
  static std::vector<std::string> builtin_names();

  const std::string& name() const { return name_; }
  const std::string& description() const { return description_; }

  /// The model phoneme index for an input label, after this set's normalisation
  /// (case folding, stress digits). An empty label is silence. nullopt if unknown.
  /// A label the table lacks goes through the set's fallback, if it has one
  /// (docs/languages.md): its fallback characters are removed and, with
  /// fallback_split, a label made of several of the table's labels (an
  /// affricate, a diphthong) is the phoneme of the first that is not a
  /// fallback_skip label (a glide or glottal onset), or of the first if all are.
  /// A label that splits into several phones is unknown (several_phones()).
  std::optional<int> lookup(std::string_view label) const;

  /// For a label lookup() does not know because it is several phones, those phones separated by
  /// spaces ("q q z z"; the first eight of more); else nullopt. An interval holds one phone: a
  /// split is one phone when, glides and glottal onsets (fallback_skip) aside, it is one piece,
  /// holds a vowel (a diphthong `eu`; espeak-ng's r-coloured `ər`), is two consonants (an
  /// affricate: `pɸ`, `tʃʲ`), or the label has a tie bar; three or more consonants without a tie
  /// bar (`qqzz`) are several phones.
  std::optional<std::string> several_phones(std::string_view label) const;

 private:
  /// The fallback split of a key: each piece of the table and its phoneme; nullopt if a byte is
  /// left over.
  std::optional<std::vector<std::pair<std::string, int>>> split(const std::string& key) const;
  /// Whether the pieces of a split, from a label with or without a tie bar, make one phone.
  bool is_one_phone(const std::vector<std::pair<std::string, int>>& pieces, bool tied) const;
  std::string fallback_key(const std::string& normalised) const;
  std::string normalise(std::string_view label) const;
  std::optional<int> fallback_lookup(const std::string& normalised, bool tied) const;

  std::string name_;
  std::string description_;
  bool case_sensitive_ = true;
  std::vector<std::string> ignored_;       // code points removed before lookup
  std::array<bool, 128> ignored_ascii_{};  // the one-byte ones among them, by byte
  std::unordered_map<std::string, int> phoneme_by_label_;
  int silence_phoneme_ = -1;
  // The fallback for labels the table lacks (all empty/false: none).
  std::vector<std::string> fallback_ignored_;  // code points removed
  bool fallback_split_ = false;                // split into the table's labels
  std::vector<std::string> fallback_skip_;     // labels passed over when another follows
  std::vector<bool> vowel_phoneme_;            // by model phoneme index: a vowel
  std::size_t longest_key_bytes_ = 0;
};

/// Picks the built-in phone set that knows every label of `labels` (in
/// builtin_names() order). If none does, returns the one with the fewest
/// unknown labels, so that the error names the closest vocabulary.
const PhoneSet& detect_phone_set(const std::vector<PhoneSet>& candidates, const std::vector<std::string_view>& labels);

}  // namespace lipsync
