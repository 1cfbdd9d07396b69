#include "lipsync/phone_set.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

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

// Found by fuzz_phone_set_from_json in CI (2026-11-24): json::value() threw a type_error, not
// an InputError, for a "format" or "description" of another type than a string.
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
                            "phones": {"A": "aa", "B": "nope"}})", "x.json", model());
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
