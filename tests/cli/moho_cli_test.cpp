// `lipsync render --format moho-dat` from the outside: the real binary writes what the core's writer
// writes for the same phonemes (default --moho-fps 24 on a track at the default --fps 30, the
// utterance ending at its last phoneme), the same bytes with --incremental and with -o, and bad
// options exit 2 naming the option. The layout itself is read back in tests/output/moho_writer_test.cpp.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../support/child_process.hpp"
#include "../support/lipsync_cli_test.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/moho_writer.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/visemes.hpp"

namespace lipsync {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class MohoCliTest : public testing::LipsyncCliTest {};

std::string closure_file(const std::string& name) {
  return (fs::path(LIPSYNC_TEST_DATA_DIR) / "closures" / name).string();
}

/// The switch data of `name` (a radio-labelled Festival or flite file) through the core, in process.
std::string core_switch_data(const std::string& name, int track_fps, int moho_fps) {
  const ArticulationModel& model = ArticulationModel::builtin();
  std::ifstream file(closure_file(name), std::ios::binary);
  std::stringstream text;
  text << file.rdbuf();
  const LabeledUtterance utterance = parse_utterance(text.str(), detect_input_format(name, text.str()), name);
  const auto segments = build_segments(utterance, model, *PhoneSet::builtin("radio", model));
  const Track track = render_track(model, segments, {.fps = track_fps});
  const VisemeClassifier classifier(model, {.vocabulary = VisemeVocabulary::rhubarb});
  const VisemeTrack visemes = compute_visemes(classifier, track);
  std::ostringstream out;
  write_moho_switch({.model = model.name(),
                     .classifier = classifier,
                     .track = track,
                     .visemes = visemes,
                     .end_us = utterance.intervals.back().end_us},
                    moho_fps, out);
  return out.str();
}

TEST_F(MohoCliTest, RenderWritesTheCoresSwitchDataAt24FpsByDefault) {
  for (const char* input : {"flite_2.psdur", "festival_4.lab"}) {
    const auto result = run({"render", closure_file(input), "--format", "moho-dat", "--phone-set", "radio"});
    ASSERT_EQ(result.status, 0) << result.err;
    EXPECT_EQ(result.out, core_switch_data(input, 30, 24)) << input;
    EXPECT_THAT(result.out, ::testing::StartsWith("MohoSwitch1\n1 rest\n")) << input;
    EXPECT_THAT(result.out, HasSubstr(" MBP\n")) << input;

    const auto at_30 = run({"render", closure_file(input), "--format", "moho-dat", "--moho-fps", "30", "--fps", "60",
                            "--phone-set", "radio"});
    ASSERT_EQ(at_30.status, 0) << at_30.err;
    EXPECT_EQ(at_30.out, core_switch_data(input, 60, 30)) << input;
  }
}

TEST_F(MohoCliTest, MohoDatIsTheSameIncrementalAndInAFile) {
  const std::string input = closure_file("festival_5.lab");
  const auto offline = run({"render", input, "--format", "moho-dat"});
  const auto incremental = run({"render", input, "--format", "moho-dat", "--incremental"});
  const auto to_file = run({"render", input, "--format", "moho-dat", "-o", "mouth.dat"});
  ASSERT_EQ(offline.status, 0) << offline.err;
  ASSERT_EQ(incremental.status, 0) << incremental.err;
  ASSERT_EQ(to_file.status, 0) << to_file.err;
  EXPECT_EQ(offline.out, incremental.out);
  EXPECT_EQ(testing::read_text(dir_ / "mouth.dat"), offline.out);
}

TEST_F(MohoCliTest, BadMohoOptionsExit2NamingTheOption) {
  const std::string input = closure_file("flite_1.psdur");
  for (const char* fps : {"0", "1001", "24.5", "x"}) {
    const auto result = run({"render", input, "--format", "moho-dat", "--moho-fps", fps});
    EXPECT_EQ(result.status, 2) << fps;
    EXPECT_THAT(result.err, HasSubstr("--moho-fps")) << fps;
  }
  const auto not_moho = run({"render", input, "--format", "rhubarb-tsv", "--moho-fps", "25"});
  EXPECT_EQ(not_moho.status, 2);
  EXPECT_THAT(not_moho.err, HasSubstr("--moho-fps needs --format moho-dat"));
  const auto shapes = run({"render", input, "--format", "moho-dat", "--extended-shapes", "GX"});
  EXPECT_EQ(shapes.status, 2);
  EXPECT_THAT(shapes.err, HasSubstr("--extended-shapes needs --format rhubarb-tsv or rhubarb-json"));
  const auto unknown = run({"render", input, "--format", "moho"});
  EXPECT_EQ(unknown.status, 2);
  EXPECT_THAT(unknown.err, HasSubstr("rhubarb-json or moho-dat)"));
  EXPECT_TRUE(fs::is_empty(dir_)) << "no file is left behind";
}

}  // namespace
}  // namespace lipsync
