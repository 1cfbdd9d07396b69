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
#include <vector>

namespace lipsync {

class ArticulationModel;

class PhoneSet {
 public:
  /// Parses a phone-set table and checks that every target it names exists in
  /// `model`. Throws InputError naming `source` and the offending label.
  static PhoneSet from_json(std::string_view json_text, std::string_view source,
                            const ArticulationModel& model);

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
  std::optional<int> lookup(std::string_view label) const;

 private:
  std::string normalise(std::string_view label) const;

  std::string name_;
  std::string description_;
  bool case_sensitive_ = true;
  std::vector<std::string> ignored_;  // code points removed before lookup
  std::array<bool, 128> ignored_ascii_{};  // the one-byte ones among them, by byte
  std::unordered_map<std::string, int> phoneme_by_label_;
  int silence_phoneme_ = -1;
};

/// Picks the built-in phone set that knows every label of `labels` (in
/// builtin_names() order). If none does, returns the one with the fewest
/// unknown labels, so that the error names the closest vocabulary.
const PhoneSet& detect_phone_set(const std::vector<PhoneSet>& candidates,
                                 const std::vector<std::string_view>& labels);

}  // namespace lipsync
