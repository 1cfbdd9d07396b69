#include "lipsync/phone_set.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "lipsync/error.hpp"
#include "lipsync/model.hpp"

namespace lipsync {
namespace {

const ArticulationModel& model() { return ArticulationModel::builtin(); }

std::string name_of(std::optional<int> phoneme) {
  return phoneme ? model().phoneme(*phoneme).name : std::string("<unknown>");
}

// A number too large for a double made nlohmann::json throw out_of_range, which escaped the
// loader as a non-InputError (the same parse step as the rig loader's fuzzing finding).
TEST(PhoneSet, ANumberThatOverflowsIsAnInputErrorNotACrash) {
  EXPECT_THROW(PhoneSet::from_json(R"({"format": 1E999999})", "big.json", model()), InputError);
}

// Found by fuzz_phone_set_from_json: json::value() threw a type_error, not an InputError, for a
// "format" or "description" of another type than a string.
TEST(PhoneSet, AFieldOfTheWrongTypeIsAnInputErrorNamingIt) {
  const auto message_for = [](const std::string& json) {
    try {
      PhoneSet::from_json(json, "typed.json", model());
    } catch (const InputError& error) {
      return std::string(error.what());
    }
    return std::string("no error");
  };
  EXPECT_THAT(message_for(R"({"format": true, "version": 1, "name": "x", "phones": {}})"),
              ::testing::HasSubstr("field 'format'"));
  EXPECT_THAT(message_for(R"({"format": "lipsync-phone-set", "version": 1, "name": "x", "description": 5,
                              "phones": {}})"),
              ::testing::HasSubstr("field 'description' must be a string"));
}

TEST(PhoneSet, EveryBuiltinSetLoadsAgainstTheBuiltinModel) {
  const auto sets = PhoneSet::builtin_all(model());
  std::vector<std::string> names;
  for (const auto& set : sets) names.push_back(set.name());
  EXPECT_THAT(names, ::testing::ElementsAre("arpabet", "radio", "timit", "ipa", "espeak", "sampa"));
}

TEST(PhoneSet, ArpabetIgnoresStressDigitsAndCase) {
  const PhoneSet set = *PhoneSet::builtin("arpabet", model());
  EXPECT_EQ(name_of(set.lookup("AA1")), "aa");
  EXPECT_EQ(name_of(set.lookup("aa0")), "aa");
  EXPECT_EQ(name_of(set.lookup("AXR")), "er");
  EXPECT_EQ(name_of(set.lookup("EM")), "m");
  EXPECT_EQ(name_of(set.lookup("sp")), "sil");
  EXPECT_EQ(name_of(set.lookup("")), "sil");
  EXPECT_EQ(set.lookup("pcl"), std::nullopt);
  EXPECT_EQ(set.lookup("QQ"), std::nullopt);
}

TEST(PhoneSet, TimitKeepsClosuresAndModelsTongueClosuresAsTheirStop) {
  const PhoneSet set = *PhoneSet::builtin("timit", model());
  EXPECT_EQ(name_of(set.lookup("pcl")), "pcl");
  EXPECT_EQ(name_of(set.lookup("bcl")), "bcl");
  EXPECT_EQ(name_of(set.lookup("tcl")), "t");
  EXPECT_EQ(name_of(set.lookup("kcl")), "k");
  EXPECT_EQ(name_of(set.lookup("h#")), "sil");
  EXPECT_EQ(name_of(set.lookup("epi")), "sil");
  EXPECT_EQ(name_of(set.lookup("ax-h")), "ax");
}

TEST(PhoneSet, IpaAndEspeakMapDiphthongsAndAffricates) {
  const PhoneSet ipa = *PhoneSet::builtin("ipa", model());
  EXPECT_EQ(name_of(ipa.lookup("aɪ")), "ay");
  EXPECT_EQ(name_of(ipa.lookup("tʃ")), "ch");
  EXPECT_EQ(name_of(ipa.lookup("ð")), "dh");
  EXPECT_EQ(name_of(ipa.lookup("ˈiː")), "iy");
  const PhoneSet espeak = *PhoneSet::builtin("espeak", model());
  EXPECT_EQ(name_of(espeak.lookup("aI")), "ay");
  EXPECT_EQ(name_of(espeak.lookup("tS")), "ch");
  EXPECT_EQ(name_of(espeak.lookup("D")), "dh");
}

TEST(PhoneSet, IpaKnowsEverySymbolOfTheIpaChart) {
  const PhoneSet ipa = *PhoneSet::builtin("ipa", model());
  // Pulmonic consonants, other symbols, vowels (IPA chart 2020).
  for (const char* symbol :
       {"p", "b", "t", "d", "ʈ", "ɖ", "c", "ɟ", "k", "ɡ", "q", "ɢ", "ʔ", "m", "ɱ", "n", "ɳ", "ɲ", "ŋ", "ɴ",
        "ʙ", "r", "ʀ", "ⱱ", "ɾ", "ɽ", "ɸ", "β", "f", "v", "θ", "ð", "s", "z", "ʃ", "ʒ", "ʂ", "ʐ", "ç", "ʝ",
        "x", "ɣ", "χ", "ʁ", "ħ", "ʕ", "h", "ɦ", "ɬ", "ɮ", "ʋ", "ɹ", "ɻ", "j", "ɰ", "l", "ɭ", "ʎ", "ʟ", "ʍ",
        "w", "ɥ", "ʜ", "ʢ", "ʡ", "ɕ", "ʑ", "ɺ", "ɧ", "i", "y", "ɨ", "ʉ", "ɯ", "u", "ɪ", "ʏ", "ʊ", "e", "ø",
        "ɘ", "ɵ", "ɤ", "o", "ə", "ɛ", "œ", "ɜ", "ɞ", "ʌ", "ɔ", "æ", "ɐ", "a", "ɶ", "ɑ", "ɒ"}) {
    EXPECT_TRUE(ipa.lookup(symbol)) << symbol;
  }
}

TEST(PhoneSet, IpaGivesOtherLanguagesTheirOwnVowelsAndBilabialFricatives) {
  const PhoneSet ipa = *PhoneSet::builtin("ipa", model());
  EXPECT_EQ(name_of(ipa.lookup("y")), "ipa_y");
  EXPECT_EQ(name_of(ipa.lookup("ø")), "ipa_ø");
  EXPECT_EQ(name_of(ipa.lookup("ɯ")), "ipa_ɯ");
  EXPECT_EQ(name_of(ipa.lookup("ɤ")), "ipa_ɤ");
  // /ɸ β/ are not closures (no sealing key frames); /ɱ ʋ/ are the labiodental closures of f v.
  EXPECT_EQ(model().phoneme(*ipa.lookup("β")).phoneme_class, PhonemeClass::consonant);
  EXPECT_EQ(model().phoneme(*ipa.lookup("ɱ")).phoneme_class, PhonemeClass::closure);
  EXPECT_EQ(model().phoneme(*ipa.lookup("ʋ")).phoneme_class, PhonemeClass::closure);
  // The alveolar trill of Spanish, Italian, Russian... leaves the lips free; English r (IPA ɹ) rounds them.
  const auto sphincter = [](std::optional<int> phoneme) {
    const auto& names = model().channels();
    for (std::size_t c = 0; c < names.size(); ++c) {
      if (names[c].name == "orbicularis_oris_upper") return model().phoneme(*phoneme).targets[c];
    }
    return -1.0;
  };
  EXPECT_EQ(name_of(ipa.lookup("r")), "ipa_r");
  EXPECT_EQ(sphincter(ipa.lookup("r")), 0.0);
  EXPECT_GT(sphincter(ipa.lookup("ɹ")), 0.5);
  // Nasal vowels are their oral vowels, written with a combining or a precomposed tilde.
  EXPECT_EQ(name_of(ipa.lookup("ɔ̃")), name_of(ipa.lookup("ɔ")));
  EXPECT_EQ(name_of(ipa.lookup("ẽ")), name_of(ipa.lookup("e")));
}

TEST(PhoneSet, IpaFallbackRemovesMarksAndSplitsLabelsIntoSymbols) {
  const PhoneSet ipa = *PhoneSet::builtin("ipa", model());
  EXPECT_EQ(name_of(ipa.lookup("yː")), "ipa_y");      // length
  EXPECT_EQ(name_of(ipa.lookup("ɯᵝ")), "ipa_ɯ");      // compressed (espeak-ng ja)
  EXPECT_EQ(name_of(ipa.lookup("a˥˩")), "ae");        // tone letters
  EXPECT_EQ(name_of(ipa.lookup("y-")), "ipa_y");      // an espeak-ng mnemonic mark
  EXPECT_EQ(name_of(ipa.lookup("tʃʲ")), "ch");        // affricate + palatalisation
  EXPECT_EQ(name_of(ipa.lookup("pɸ")), "p");          // an affricate: its stop
  EXPECT_EQ(name_of(ipa.lookup("eu")), "ey");         // a diphthong: its onset
  EXPECT_EQ(name_of(ipa.lookup("ja")), "ae");         // a glide onset is passed over
  EXPECT_EQ(name_of(ipa.lookup("ʔi")), "iy");         // so is a glottal one
  EXPECT_EQ(name_of(ipa.lookup("☃")), "<unknown>");   // not a symbol of the table
  EXPECT_EQ(name_of(ipa.lookup("aI")), "<unknown>");  // espeak's mnemonic: I is no IPA symbol
  EXPECT_EQ(name_of(ipa.lookup("ː")), "<unknown>");   // nothing left
}

TEST(PhoneSet, IpaLabelOfSeveralPhonesIsUnknownAndNamesThem) {
  // An interval holds one phone: three or more consonants with no tie bar (no affricate, no
  // diphthong) are no phoneme, and several_phones() says why.
  const PhoneSet ipa = *PhoneSet::builtin("ipa", model());
  EXPECT_EQ(name_of(ipa.lookup("qqzz")), "<unknown>");
  EXPECT_EQ(ipa.several_phones("qqzz"), "q q z z");
  EXPECT_EQ(ipa.several_phones("ptk"), "p t k");
  EXPECT_EQ(ipa.several_phones(std::string(100000, 'k')), "k k k k k k k k … (100000 in all)");  // a short error
  EXPECT_EQ(name_of(ipa.lookup("t͡sʃ")), "t");  // a tie bar makes one phone of its symbols
  EXPECT_EQ(ipa.several_phones("t͡sʃ"), std::nullopt);
  EXPECT_EQ(name_of(ipa.lookup("eau")), "ey");        // a triphthong: vowels alone
  EXPECT_EQ(name_of(ipa.lookup("ər")), "ax");         // espeak-ng's r-coloured vowel (Mandarin 二)
  EXPECT_EQ(ipa.several_phones("pɸ"), std::nullopt);  // known: an affricate
  EXPECT_EQ(ipa.several_phones("☃"), std::nullopt);   // unknown, but not for being several phones
  EXPECT_EQ(ipa.several_phones("aa"), std::nullopt);  // long a, a vowel twice
}

TEST(PhoneSet, IpaLookupOfAnyBytesGivesAPhonemeOrNothing) {
  // Random labels (fixed seed) of IPA symbols, diacritics, espeak-ng marks, ASCII and bytes that are
  // no UTF-8 at all (stray continuation bytes, cut sequences): the fallback's split never crashes,
  // loops or names a phoneme the model lacks.
  const PhoneSet ipa = *PhoneSet::builtin("ipa", model());
  const std::vector<std::string> pieces = {"a", "y", "t",  "ʃ", "ɔ",    "\xCC\x83", "ː",        "ʲ",    "ʰ", "-", "#",
                                           "j", "ʔ", "ɟʝ", "˥", "\x80", "\xCC",     "\xE2\x98", "\xFF", "I", "@", " "};
  std::uint32_t state = 12345;
  const auto next = [&] { return state = state * 1664525U + 1013904223U; };
  std::size_t known = 0;
  for (int i = 0; i < 20000; ++i) {
    std::string label;
    for (std::uint32_t n = next() % 6; n > 0; --n) label += pieces[next() % pieces.size()];
    if (const auto index = ipa.lookup(label)) {
      ++known;
      EXPECT_GE(*index, 0);
      EXPECT_LT(static_cast<std::size_t>(*index), model().phonemes().size());
    }
  }
  EXPECT_GT(known, 1000U);  // the pieces combine into known labels often
}

TEST(PhoneSet, AModelWithoutTheIpaPhonemesKeepsEverySetTheIpaOneWithEnglishSubstitutes) {
  // A model of one's own made from `lipsync model dump` before the ipa_ phonemes existed: the built-in
  // sets still load against it (auto detection loads them all), the ipa set mapping what it mapped
  // before as before.
  nlohmann::json json = nlohmann::json::parse(ArticulationModel::builtin_json());
  for (auto it = json["phonemes"].begin(); it != json["phonemes"].end();) {
    it = it.key().starts_with("ipa_") ? json["phonemes"].erase(it) : std::next(it);
  }
  const ArticulationModel english = ArticulationModel::from_json(json.dump(), "english-only.json");
  ASSERT_FALSE(english.find_phoneme("ipa_y"));
  EXPECT_EQ(PhoneSet::builtin_all(english).size(), PhoneSet::builtin_names().size());
  const PhoneSet ipa = *PhoneSet::builtin("ipa", english);
  const auto name = [&](std::string_view label) {
    const auto phoneme = ipa.lookup(label);
    return phoneme ? english.phoneme(*phoneme).name : std::string("<unknown>");
  };
  EXPECT_EQ(name("ø"), "ow");
  EXPECT_EQ(name("œ"), "ao");
  EXPECT_EQ(name("ɸ"), "f");
  EXPECT_EQ(name("β"), "v");
  EXPECT_EQ(name("r"), "r");
  EXPECT_EQ(name("ʁ"), "r");
  EXPECT_EQ(name("y"), "uw");
  EXPECT_EQ(name("ɔ̃"), "ao");
}

TEST(PhoneSet, DetectionStillTellsEspeakMnemonicsFromIpa) {
  const auto sets = PhoneSet::builtin_all(model());
  EXPECT_EQ(detect_phone_set(sets, {"h", "@", "l", "oU"}).name(), "espeak");
  EXPECT_EQ(detect_phone_set(sets, {"b", "ɔ̃", "ʒ", "u", "ʁ"}).name(), "ipa");
  EXPECT_EQ(detect_phone_set(sets, {"ɡ", "uː", "t", "ə", "n", "pf", "yː"}).name(), "ipa");
}

TEST(PhoneSet, DetectionPicksTheFirstSetThatKnowsEveryLabel) {
  const auto sets = PhoneSet::builtin_all(model());
  EXPECT_EQ(detect_phone_set(sets, {"HH", "AH0", "L", "OW1"}).name(), "arpabet");
  EXPECT_EQ(detect_phone_set(sets, {"pau", "hh", "ax", "l", "ow"}).name(), "radio");
  EXPECT_EQ(detect_phone_set(sets, {"h#", "pcl", "p", "iy"}).name(), "timit");
  EXPECT_EQ(detect_phone_set(sets, {"h", "ə", "l", "oʊ"}).name(), "ipa");
}

TEST(PhoneSet, TableErrorsNameTheLabel) {
  try {
    PhoneSet::from_json(R"({"format": "lipsync-phone-set", "version": 1, "name": "x",
                            "phones": {"A": "aa", "B": "nope"}})",
                        "x.json", model());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::AllOf(::testing::HasSubstr("x.json"), ::testing::HasSubstr("'B'"),
                                           ::testing::HasSubstr("'nope'")));
  }
  EXPECT_THROW(PhoneSet::from_json(R"({"format": "lipsync-phone-set", "version": 1, "name": "x",
                                       "case_sensitive": false, "phones": {"A": "aa", "a": "aa"}})",
                                   "x.json", model()),
               InputError);
}

}  // namespace
}  // namespace lipsync
