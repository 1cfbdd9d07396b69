#include "lipsync/model.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <sstream>

#include "lipsync/error.hpp"
#include "test_model.hpp"

namespace lipsync {
namespace {

using ::testing::HasSubstr;

std::string load_error(const std::string& json) {
  try {
    ArticulationModel::from_json(json, "my-model.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

/// The test model with one substring replaced.
std::string edited(const std::string& from, const std::string& to) {
  std::string text = testing::kTestModelJson;
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return text.replace(at, from.size(), to);
}

TEST(ArticulationModel, BuiltinModelLoadsWithTheRequiredChannels) {
  const ArticulationModel& model = ArticulationModel::builtin();
  std::vector<std::string> names;
  for (const auto& channel : model.channels()) names.push_back(channel.name);
  for (const char* required :
       {"zygomaticus_major_left", "zygomaticus_major_right", "levator_labii_superioris_left",
        "levator_labii_superioris_right", "risorius_left", "risorius_right", "depressor_anguli_oris_left",
        "depressor_anguli_oris_right", "depressor_labii_inferioris_left", "depressor_labii_inferioris_right",
        "mentalis", "orbicularis_oris_upper", "orbicularis_oris_lower", "jaw_rotation", "tongue_raise",
        "tongue_protrusion"}) {
    EXPECT_THAT(names, ::testing::Contains(std::string(required)));
  }
}

TEST(ArticulationModel, BuiltinModelFollowsItsPhoneticRules) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const auto channel = [&](std::string_view name) {
    for (std::size_t c = 0; c < model.channel_count(); ++c) {
      if (model.channels()[c].name == name) return c;
    }
    ADD_FAILURE() << "no channel " << name;
    return std::size_t{0};
  };
  const auto target = [&](const char* phoneme, std::string_view name) {
    return model.phoneme(*model.find_phoneme(phoneme)).targets[channel(name)];
  };
  const auto alpha = [&](const char* phoneme, std::string_view name) {
    return model.phoneme(*model.find_phoneme(phoneme)).dominance[channel(name)].alpha;
  };
  EXPECT_GT(target("aa", "jaw_rotation"), target("iy", "jaw_rotation"));  // open vowels open the jaw
  EXPECT_GT(target("uw", "orbicularis_oris_upper"), target("iy", "orbicularis_oris_upper"));  // rounding
  for (const char* bilabial : {"pcl", "bcl", "m"}) {
    EXPECT_GT(alpha(bilabial, "orbicularis_oris_upper"), alpha(bilabial, "tongue_raise")) << bilabial;
    EXPECT_GT(alpha(bilabial, "orbicularis_oris_upper"), alpha("aa", "orbicularis_oris_upper")) << bilabial;
  }
  EXPECT_GT(target("f", "orbicularis_oris_lower"), target("aa", "orbicularis_oris_lower"));  // lower lip tuck
  EXPECT_GT(target("th", "tongue_protrusion"), target("s", "tongue_protrusion"));            // dentals
  EXPECT_GT(target("t", "tongue_raise"), target("aa", "tongue_raise"));                      // alveolars
  EXPECT_LT(alpha("ax", "jaw_rotation"), alpha("aa", "jaw_rotation"));                       // schwa is weak
  EXPECT_LT(alpha("hh", "jaw_rotation"), alpha("aa", "jaw_rotation"));
  EXPECT_EQ(model.phoneme(*model.find_phoneme("p")).closure_phoneme, *model.find_phoneme("pcl"));
}

TEST(ArticulationModel, RetargetsChannelsToArkitByTheModelMatrix) {
  const ArticulationModel& model = testing::test_model();
  std::vector<float> arkit(kArkitNames.size());
  const std::vector<float> channels = {0.3F, 0.7F, 0.0F};
  model.retarget_to_arkit(channels, arkit);
  const auto jaw_open = std::find(kArkitNames.begin(), kArkitNames.end(), "jawOpen") - kArkitNames.begin();
  for (std::size_t i = 0; i < arkit.size(); ++i) {
    EXPECT_FLOAT_EQ(arkit[i], static_cast<std::ptrdiff_t>(i) == jaw_open ? 0.7F : 0.0F) << kArkitNames[i];
  }
}

TEST(ArticulationModel, ValidationErrorsNameThePhonemeAndField) {
  EXPECT_THAT(load_error(edited(R"("lips": 0.1, "jaw": 0.1, "tongue": -0.5)", R"("lips": 1.5)")),
              ::testing::AllOf(HasSubstr("my-model.json"), HasSubstr("phoneme 'low'"), HasSubstr("'lips'"),
                               HasSubstr("outside the channel range")));
  EXPECT_THAT(load_error(edited(R"("lips": 0.9, "jaw": 0.9)", R"("lipz": 0.9, "jaw": 0.9)")),
              ::testing::AllOf(HasSubstr("phoneme 'high'"), HasSubstr("unknown channel 'lipz'")));
  EXPECT_THAT(load_error(edited(R"("sil": {"class": "silence", "dominance": {"alpha": 0.5}})",
                                R"("sil": {"class": "silence", "dominance": {"alpha": 0}})")),
              ::testing::AllOf(HasSubstr("phoneme 'sil'"), HasSubstr("'alpha'"), HasSubstr("> 0")));
  EXPECT_THAT(load_error(edited(R"("dominance": {"c": 2,)", R"("dominance": {"c": 0.5,)")),
              ::testing::AllOf(HasSubstr("phoneme 'sharp'"), HasSubstr("'c'")));
  EXPECT_THAT(load_error(edited(R"("class": "release", "closure": "pcl",)", R"("class": "release",)")),
              ::testing::AllOf(HasSubstr("phoneme 'p'"), HasSubstr("'closure'"), HasSubstr("required")));
  EXPECT_THAT(load_error(edited(R"("closure": "pcl")", R"("closure": "aa")")),
              ::testing::AllOf(HasSubstr("phoneme 'p'"), HasSubstr("not of class closure")));
  EXPECT_THAT(
      load_error(edited(R"("class": "vowel", "targets": {"lips": 0.2)", R"("class": "vowl", "targets": {"lips": 0.2)")),
      ::testing::AllOf(HasSubstr("phoneme 'aa'"), HasSubstr("'class'"), HasSubstr("vowl")));
  EXPECT_THAT(load_error(edited(R"("sil": {"class": "silence")", R"("pause": {"class": "silence")")),
              HasSubstr("'sil'"));
  EXPECT_THAT(load_error(edited(R"("jawOpen")", R"("jawOpened")")), HasSubstr("unknown ARKit blendshape 'jawOpened'"));
  EXPECT_THAT(load_error(edited(R"("t_off_ms": 10)", R"("t_off_ms": 10, "tof": 1)")),
              ::testing::AllOf(HasSubstr("phoneme 'sharp'"), HasSubstr("unknown field 'tof'")));
  EXPECT_THAT(load_error("{ not json"), ::testing::AllOf(HasSubstr("my-model.json"), HasSubstr("not valid JSON")));
  EXPECT_THAT(load_error(edited(R"("version": 1)", R"("version": 2)")), HasSubstr("unsupported version"));
}

TEST(ArticulationModel, RejectsEveryBadModelFile) {
  const std::string dir = std::string(LIPSYNC_TEST_DATA_DIR) + "/models/";
  for (const char* name : {"bad_target_out_of_range.json", "bad_unknown_channel.json", "bad_alpha.json",
                           "bad_exponent.json", "bad_release_without_closure.json", "bad_missing_sil.json"}) {
    std::ifstream file(dir + name);
    ASSERT_TRUE(file) << "missing fixture " << dir + name;
    std::stringstream text;
    text << file.rdbuf();
    EXPECT_THROW(ArticulationModel::from_json(text.str(), name), InputError) << name;
  }
}

// Found by fuzzing (the rig loader had the same parse step): a number too large for a double made
// nlohmann::json throw out_of_range, which escaped as a non-InputError.
TEST(ArticulationModel, ANumberThatOverflowsIsAnInputErrorNotACrash) {
  try {
    ArticulationModel::from_json(R"({"format": "lipsync-articulation-model", "version": 1E999999})", "big.json");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("big.json"));
  }
}

TEST(ArticulationModel, DumpedBuiltinJsonLoadsAgain) {
  const ArticulationModel model = ArticulationModel::from_json(ArticulationModel::builtin_json(), "dump");
  EXPECT_EQ(model.phonemes().size(), ArticulationModel::builtin().phonemes().size());
  EXPECT_EQ(model.arkit_matrix(), ArticulationModel::builtin().arkit_matrix());
}

TEST(ArticulationModel, ArkitMouthCloseNeverExceedsJawOpen) {
  // mouthClose closes the lips against the jaw's opening; beyond jawOpen it would push them
  // through each other in an ARKit rig.
  const ArticulationModel& model = ArticulationModel::builtin();
  const auto index = [](std::string_view name) {
    return static_cast<std::size_t>(std::find(kArkitNames.begin(), kArkitNames.end(), name) - kArkitNames.begin());
  };
  std::vector<float> shapes(kArkitNames.size());
  for (const PhonemeSpec& phoneme : model.phonemes()) {
    const std::vector<float> channels(phoneme.targets.begin(), phoneme.targets.end());
    model.retarget_to_arkit(channels, shapes);
    EXPECT_LE(shapes[index("mouthClose")], shapes[index("jawOpen")]) << phoneme.name;
  }
  // A bilabial closure is sealed: mouthClose reaches jawOpen.
  const auto& m = model.phoneme(*model.find_phoneme("m"));
  model.retarget_to_arkit(std::vector<float>(m.targets.begin(), m.targets.end()), shapes);
  EXPECT_GT(shapes[index("jawOpen")], 0.05F);
  EXPECT_EQ(shapes[index("mouthClose")], shapes[index("jawOpen")]);
}

}  // namespace
}  // namespace lipsync
