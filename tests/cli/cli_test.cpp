// End-to-end tests of the `lipsync` command line: each test runs the real
// binary in a fresh temporary directory (fork + exec, stdout and stderr
// captured to files outside it) and checks the exit status, the messages and
// which files exist afterwards. Fixtures live in tests/data/cli/.
#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "../support/child_process.hpp"
#include "../support/lipsync_cli_test.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/model.hpp"
#include "lipsync/moho_writer.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/release_delay.hpp"
#include "lipsync/setting_ranges.hpp"
#include "lipsync/track_writer.hpp"
#include "lipsync/viseme_writer.hpp"

namespace lipsync {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::make_temp_dir;
using ::testing::Not;
using testing::read_text;
using testing::run_program;
using testing::RunResult;
using ::testing::StartsWith;
using testing::write_text;

const fs::path kFixtures = fs::path(LIPSYNC_TEST_DATA_DIR) / "cli";

std::string fixture(std::string_view name) { return (kFixtures / name).string(); }

class CliTest : public testing::LipsyncCliTest {};

std::string describe(const RunResult& result) {
  return "exit " + std::to_string(result.status) + "\n--- stderr:\n" + result.err + "--- stdout (start):\n" +
         result.out.substr(0, 400);
}

// ---------------------------------------------------------------------------
// Help and version

// A TextGrid with three phone intervals; the second's label, on line 22 (its xmin on line 20), is `label`.
std::string three_phone_grid(const std::string& label) {
  return "File type = \"ooTextFile\"\nObject class = \"TextGrid\"\n\nxmin = 0\nxmax = 0.6\ntiers? <exists>\n"
         "size = 1\nitem []:\n    item [1]:\n        class = \"IntervalTier\"\n        name = \"phones\"\n"
         "        xmin = 0\n        xmax = 0.6\n        intervals: size = 3\n        intervals [1]:\n"
         "            xmin = 0\n            xmax = 0.2\n            text = \"sil\"\n        intervals [2]:\n"
         "            xmin = 0.2\n            xmax = 0.4\n            text = \"" +
         label +
         "\"\n        intervals [3]:\n            xmin = 0.4\n            xmax = 0.6\n            text = \"aa\"\n";
}

TEST_F(CliTest, HelpListsEveryCommand) {
  const RunResult result = run({"--help"});
  ASSERT_EQ(result.status, 0) << describe(result);
  for (const char* command : {"render", "demo", "model", "phone-sets", "voices"}) {
    EXPECT_THAT(result.out, HasSubstr("\n  " + std::string(command) + " ")) << command;
  }
}

TEST_F(CliTest, NoCommandIsAUsageError) {
  EXPECT_EQ(run({}).status, 2);
  const RunResult result = run({"frobnicate"});
  EXPECT_EQ(result.status, 2);
  EXPECT_EQ(result.err, "lipsync: error: unknown command 'frobnicate' (see 'lipsync --help')\n");
}

TEST_F(CliTest, VersionPrintsOneLine) {
  const RunResult result = run({"--version"});
  EXPECT_EQ(result.status, 0);
  EXPECT_THAT(result.out, StartsWith("lipsync "));
}

// The entries of a --help text, by option ("--fps N"): each entry's first line plus its wrapped
// continuation lines, joined with spaces.
std::map<std::string, std::string> help_entries(const std::string& help) {
  std::map<std::string, std::string> entries;
  std::string* last = nullptr;
  std::istringstream lines(help);
  for (std::string line; std::getline(lines, line);) {
    const auto text = line.find_first_not_of(' ');
    if (text == std::string::npos) continue;
    if (line[text] == '-') {
      // "  -o, --output FILE  help": the key is the long form with its value name.
      const auto long_form = line.find("--", text);
      const auto gap = line.find("  ", long_form);
      last = &entries[line.substr(long_form, gap == std::string::npos ? std::string::npos : gap - long_form)];
      *last = line;
    } else if (last && text > 10) {
      *last += " " + line.substr(text);
    }
  }
  return entries;
}

TEST_F(CliTest, RenderHelpDocumentsEveryOptionWithItsDefault) {
  const RunResult result = run({"render", "--help"});
  ASSERT_EQ(result.status, 0) << describe(result);
  EXPECT_THAT(result.out, StartsWith("Usage: lipsync render INPUT [options]\n"));
  const std::vector<std::pair<std::string, std::string>> options = {
      {"--output FILE", "stdout"},
      {"--format FORMAT", "json"},
      {"--fps N", "30"},
      {"--model FILE", "the built-in model"},
      {"--phone-set NAME", "auto"},
      {"--input-format FORMAT", "detected"},
      {"--tier NAME", "phones"},
      {"--sample-rate HZ", "16000"},
      {"--closure-fraction F", "0.6"},
      {"--fixed-rate", "off"},
      {"--incremental", "off"},
      {"--lookahead N", "7"},
      {"--extended-shapes LETTERS", "GHX"},
  };
  std::map<std::string, std::string> line_of = help_entries(result.out);
  for (const auto& [option, value] : options) {
    ASSERT_TRUE(line_of.count(option)) << option << " missing from:\n" << result.out;
    EXPECT_THAT(line_of[option], HasSubstr("(default: ")) << option;
    EXPECT_THAT(line_of[option], HasSubstr(value)) << option;
  }
  EXPECT_THAT(line_of["--output FILE"], HasSubstr("-o, --output FILE"));
}

TEST_F(CliTest, HelpQuotesTheRangesAndDefaultsThatTheChecksEnforce) {
  const auto range = [](const IntSetting& setting) {
    return std::to_string(setting.min) + " to " + std::to_string(setting.max);
  };
  const auto with_default = [](const IntSetting& setting) {
    return "(default: " + std::to_string(setting.default_value) + ")";
  };
  struct Expected {
    std::vector<std::string> command;
    std::string option;
    IntSetting setting;
  };
  for (const Expected& expected : std::vector<Expected>{
           {{"stream"}, "--fps N", kFpsSetting},  // render's: RhubarbFormatsDefaultToRhubarbs…
           {{"render"}, "--lookahead N", kLookaheadSetting},
           {{"render"}, "--mesh-subdivision N", kMeshSubdivisionSetting},
           {{"stream"}, "--lookahead N", kLookaheadSetting},
           {{"loadtest"}, "--mesh-subdivision N", kMeshSubdivisionSetting},
       }) {
    std::vector<std::string> args = expected.command;
    args.push_back("--help");
    const RunResult result = run(args);
    ASSERT_EQ(result.status, 0) << describe(result);
    const auto entries = help_entries(result.out);
    ASSERT_TRUE(entries.count(expected.option)) << expected.option << " missing from:\n" << result.out;
    EXPECT_THAT(entries.at(expected.option), HasSubstr(range(expected.setting))) << args[0];
    EXPECT_THAT(entries.at(expected.option), HasSubstr(with_default(expected.setting))) << args[0];
  }
  // The check behind --fps quotes the same range as its help.
  const RunResult too_fast = run({"render", fixture("hello.json"), "--fps", std::to_string(kFpsSetting.max + 1)});
  EXPECT_EQ(too_fast.status, 2);
  EXPECT_THAT(too_fast.err, HasSubstr(range(kFpsSetting)));
  const RunResult play_help = run({"play", "--help"});
  EXPECT_THAT(help_entries(play_help.out)["--rate N"], HasSubstr(range(kFpsSetting)));
  // stream's --playout-delay: its default is the release delay plus a margin, and the figure the
  // help quotes for the exact lookahead is that sum.
  const std::string playout = help_entries(run({"stream", "--help"}).out)["--playout-delay MS"];
  EXPECT_THAT(playout, HasSubstr("0 to 600000"));
  std::smatch quoted;
  const std::string pattern = "release delay on read speech \\+ ([0-9]+) \\(([0-9]+) at lookahead ([0-9]+)\\)";
  ASSERT_TRUE(std::regex_search(playout, quoted, std::regex(pattern))) << playout;
  const int margin_ms = std::stoi(quoted[1]), quoted_ms = std::stoi(quoted[2]), lookahead = std::stoi(quoted[3]);
  EXPECT_EQ(lookahead, kLookaheadSetting.max);
  EXPECT_EQ(quoted_ms, read_speech_release_delay_us(lookahead) / 1000 + margin_ms);
}

TEST_F(CliTest, EveryCommandHasHelp) {
  for (const std::vector<std::string>& args : std::vector<std::vector<std::string>>{{"demo", "--help"},
                                                                                    {"model", "--help"},
                                                                                    {"model", "dump", "--help"},
                                                                                    {"phone-sets", "-h"},
                                                                                    {"voices", "-h"}}) {
    const RunResult result = run(args);
    EXPECT_EQ(result.status, 0) << args[0];
    EXPECT_THAT(result.out, StartsWith("Usage: lipsync ")) << args[0];
    EXPECT_THAT(result.out, HasSubstr("-h, --help")) << args[0];
  }
}

TEST_F(CliTest, HelpAndErrorsListExactlyTheFormatsTheCoreNames) {
  std::vector<std::string_view> render_formats;
  for (const auto& entry : kTrackFormats) render_formats.push_back(entry.name);
  for (const auto& entry : kVisemeFormats) render_formats.push_back(entry.name);
  for (const auto& entry : kMouthSwitchFormats) render_formats.push_back(entry.name);
  const std::string help = help_entries(run({"render", "--help"}).out)["--format FORMAT"];
  const RunResult unknown = run({"render", "--format", "nope", "x.lab"});
  EXPECT_EQ(unknown.status, 2) << describe(unknown);
  for (const std::string_view name : render_formats) {
    EXPECT_THAT(help, HasSubstr(std::string(name))) << name;
    EXPECT_THAT(unknown.err, HasSubstr(std::string(name))) << name;
  }
  EXPECT_THAT(unknown.err, HasSubstr("rhubarb-json or moho-dat)"));
  // Every name offered is accepted (a missing input file is the next complaint, not the format).
  for (const std::string_view name : render_formats) {
    const RunResult result = run({"render", "--format", std::string(name), "missing.lab"});
    EXPECT_THAT(result.err, Not(HasSubstr("--format"))) << name << ": " << result.err;
  }
  const RunResult input = run({"render", "--input-format", "nope", "x.lab"});
  for (const auto& entry : kInputFormats) EXPECT_THAT(input.err, HasSubstr(std::string(entry.name)));
  EXPECT_THAT(input.err, HasSubstr("pho or flite)"));
}

// ---------------------------------------------------------------------------
// demo

TEST_F(CliTest, DemoWritesTheFileAndPrintsThePath) {
  const RunResult result = run({"demo"});
  ASSERT_EQ(result.status, 0) << describe(result);
  EXPECT_EQ(listing(), std::vector<std::string>{"lipsync-demo.json"});
  const fs::path written = fs::canonical(dir_ / "lipsync-demo.json");
  EXPECT_THAT(result.out, HasSubstr(written.string()));
  EXPECT_EQ(std::count(result.out.begin(), result.out.end(), '\n'), 1) << result.out;
  EXPECT_TRUE(result.err.empty()) << result.err;

  const auto track = nlohmann::json::parse(read_text(written));
  EXPECT_EQ(track["format"], "lipsync-track");
  EXPECT_EQ(track["fps"], 30);
  const std::size_t frames = track["frames"].size();
  EXPECT_GE(frames, 59U) << "1.96 s at 30 fps";
  EXPECT_THAT(result.out, HasSubstr(" " + std::to_string(frames) + " frames"));
  EXPECT_THAT(result.out, HasSubstr("1.960000 s"));
}

TEST_F(CliTest, DemoFollowsFormatAndOutput) {
  RunResult result = run({"demo", "--format", "arkit-csv", "--fps", "60"});
  ASSERT_EQ(result.status, 0) << describe(result);
  EXPECT_EQ(listing(), std::vector<std::string>{"lipsync-demo.arkit.csv"});
  EXPECT_THAT(read_text(dir_ / "lipsync-demo.arkit.csv"), StartsWith("Timecode,BlendShapeCount,EyeBlinkLeft,"));

  result = run({"demo", "-o", "-"});
  ASSERT_EQ(result.status, 0) << describe(result);
  EXPECT_TRUE(nlohmann::json::accept(result.out));
  EXPECT_THAT(result.err, HasSubstr("standard output"));
}

// ---------------------------------------------------------------------------
// render

TEST_F(CliTest, RenderJsonHasTheGridFrames) {
  // hello.json ends at 1.238 s: grid frames at round(i·10⁶/fps) < 1.238 s.
  for (const auto& [fps, expected] : std::vector<std::pair<int, std::size_t>>{{30, 38}, {60, 75}, {24, 30}}) {
    const RunResult result = run({"render", fixture("hello.json"), "--fixed-rate", "--fps", std::to_string(fps)});
    ASSERT_EQ(result.status, 0) << describe(result);
    const auto track = nlohmann::json::parse(result.out);
    EXPECT_EQ(track["fps"], fps);
    ASSERT_EQ(track["frames"].size(), expected) << fps << " fps";
    for (std::size_t i = 0; i < expected; ++i) {
      const auto& frame = track["frames"][i];
      const auto t_us = static_cast<std::int64_t>((static_cast<std::int64_t>(i) * 1'000'000 + fps / 2) / fps);
      EXPECT_EQ(frame["t_us"].get<std::int64_t>(), t_us) << i;
      EXPECT_EQ(frame["kind"], "uniform");
      EXPECT_EQ(frame["values"].size(), track["channels"].size());
      EXPECT_EQ(frame["arkit"].size(), 52U);
    }
  }
}

TEST_F(CliTest, RenderAddsKeyFramesAtClosures) {
  const RunResult result = run({"render", fixture("bump_map.json")});
  ASSERT_EQ(result.status, 0) << describe(result);
  const auto track = nlohmann::json::parse(result.out);
  std::set<std::string> kinds;
  std::int64_t previous = -1;
  for (const auto& frame : track["frames"]) {
    kinds.insert(frame["kind"].get<std::string>());
    EXPECT_GT(frame["t_us"].get<std::int64_t>(), previous);
    previous = frame["t_us"].get<std::int64_t>();
  }
  EXPECT_TRUE(kinds.count("closure_start"));
  EXPECT_TRUE(kinds.count("closure_end"));
}

TEST_F(CliTest, RenderToFileEqualsStdoutAndReadsStdin) {
  const RunResult to_stdout = run({"render", fixture("bump_map.lab"), "--format", "csv"});
  ASSERT_EQ(to_stdout.status, 0) << describe(to_stdout);
  const RunResult to_file = run({"render", fixture("bump_map.lab"), "--format=csv", "-o", "track.csv"});
  ASSERT_EQ(to_file.status, 0) << describe(to_file);
  EXPECT_TRUE(to_file.out.empty());
  EXPECT_EQ(listing(), std::vector<std::string>{"track.csv"});
  EXPECT_EQ(read_text(dir_ / "track.csv"), to_stdout.out);

  const RunResult from_stdin =
      run({"render", "-", "--format", "csv"}, {.stdin_file = kFixtures / "bump_map.lab", .path_env = std::nullopt});
  ASSERT_EQ(from_stdin.status, 0) << describe(from_stdin);
  EXPECT_EQ(from_stdin.out, to_stdout.out);
}

TEST_F(CliTest, EveryInputFormatRendersTheSameUtterance) {
  // "bump the map" with the same timings in five formats and four phone sets
  // (arpabet, radio, sampa; TextGrid detected): the same model phonemes, so the
  // same bytes. The TIMIT file differs on purpose (explicit closure labels).
  const RunResult reference = run({"render", fixture("bump_map.psdur"), "--format", "csv"});
  ASSERT_EQ(reference.status, 0) << describe(reference);
  EXPECT_THAT(reference.out, StartsWith("t,t_us,kind,"));
  EXPECT_GT(std::count(reference.out.begin(), reference.out.end(), '\n'), 30);
  for (const char* name : {"bump_map.json", "bump_map.lab", "bump_map.pho", "bump_map.TextGrid"}) {
    const RunResult result = run({"render", fixture(name), "--format", "csv"});
    ASSERT_EQ(result.status, 0) << name << "\n" << describe(result);
    EXPECT_TRUE(result.out == reference.out)
        << name << " renders differently from bump_map.psdur: do the phone-set tables map its labels "
        << "to the same model phonemes?";
  }
  const RunResult timit = run({"render", fixture("bump_map.PHN"), "--format", "csv"});
  ASSERT_EQ(timit.status, 0) << describe(timit);
  EXPECT_THAT(timit.out, StartsWith("t,t_us,kind,"));
}

TEST_F(CliTest, IncrementalOutputIsByteIdenticalToOffline) {
  const std::vector<std::string> inputs = {"hello.json",   "bump_map.json", "bump_map.psdur",   "bump_map.lab",
                                           "bump_map.PHN", "bump_map.pho",  "bump_map.TextGrid"};
  const std::vector<std::vector<std::string>> option_sets = {
      {}, {"--fps", "60"}, {"--fixed-rate"}, {"--lookahead", "2"}, {"--fps", "24", "--closure-fraction", "0.3"}};
  for (const std::string& input : inputs) {
    for (const char* format : {"json", "csv", "arkit-csv"}) {
      for (const auto& options : option_sets) {
        std::vector<std::string> args = {"render", fixture(input), "--format", format};
        args.insert(args.end(), options.begin(), options.end());
        const RunResult offline = run(args);
        args.push_back("--incremental");
        const RunResult incremental = run(args);
        std::string label = input + " " + format;
        for (const auto& option : options) label += " " + option;
        ASSERT_EQ(offline.status, 0) << label << "\n" << describe(offline);
        ASSERT_EQ(incremental.status, 0) << label << "\n" << describe(incremental);
        EXPECT_FALSE(offline.out.empty()) << label;
        EXPECT_TRUE(offline.out == incremental.out) << label << ": incremental output differs";
      }
    }
  }
}

// Rhubarb Lip Sync's output formats, read as its README documents them: TSV lines
// "<seconds>\t<shape>" (first at 0.00, the last one the end of the recording with a closed mouth,
// X or A); JSON {"metadata":{"soundFile","duration"},"mouthCues":[{"start","end","value"}]} with
// each cue's end the next one's start. Shapes are A-F plus the extended G, H, X.
struct RhubarbCueRead {
  double start = 0, end = 0;
  std::string shape;
};

bool is_rhubarb_shape(const std::string& shape) {
  return shape.size() == 1 && std::string("ABCDEFGHX").find(shape[0]) != std::string::npos;
}

/// Seconds as Rhubarb writes them: digits, '.', exactly two digits.
double rhubarb_seconds(const std::string& text) {
  const auto dot = text.find('.');
  if (dot == std::string::npos || dot == 0 || text.size() != dot + 3 ||
      text.find_first_not_of("0123456789.") != std::string::npos) {
    throw std::runtime_error("not Rhubarb seconds: '" + text + "'");
  }
  return std::stod(text);
}

std::vector<RhubarbCueRead> read_rhubarb_tsv(const std::string& text) {
  std::vector<RhubarbCueRead> cues;
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    const auto tab = line.find('\t');
    if (tab == std::string::npos) throw std::runtime_error("TSV line without a tab: '" + line + "'");
    const RhubarbCueRead cue{rhubarb_seconds(line.substr(0, tab)), 0, line.substr(tab + 1)};
    if (!is_rhubarb_shape(cue.shape)) throw std::runtime_error("not a Rhubarb shape: '" + cue.shape + "'");
    if (!cues.empty()) cues.back().end = cue.start;
    cues.push_back(cue);
  }
  return cues;
}

TEST_F(CliTest, RhubarbTsvAndJsonReadBackAsRhubarbDocumentsThem) {
  for (const char* input : {"festival_2.lab", "flite_4.psdur"}) {
    const std::string path = (fs::path(LIPSYNC_TEST_DATA_DIR) / "closures" / input).string();
    const RunResult tsv = run({"render", path, "--format", "rhubarb-tsv"});
    const RunResult json = run({"render", path, "--format", "rhubarb-json"});
    ASSERT_EQ(tsv.status, 0) << describe(tsv);
    ASSERT_EQ(json.status, 0) << describe(json);

    std::vector<RhubarbCueRead> from_tsv = read_rhubarb_tsv(tsv.out);
    ASSERT_GE(from_tsv.size(), 10U) << input;
    EXPECT_EQ(from_tsv.front().start, 0.0) << input;
    const RhubarbCueRead last = from_tsv.back();  // the end marker line
    EXPECT_TRUE(last.shape == "X") << input << ": last line " << last.shape;
    from_tsv.pop_back();
    for (std::size_t i = 1; i < from_tsv.size(); ++i) {
      EXPECT_LT(from_tsv[i - 1].start, from_tsv[i].start) << input << " cue " << i;
      EXPECT_NE(from_tsv[i - 1].shape, from_tsv[i].shape) << input << " cue " << i;
    }
    EXPECT_LT(from_tsv.back().start, last.start) << input;
    EXPECT_EQ(from_tsv.back().end, last.start) << input;

    const nlohmann::json doc = nlohmann::json::parse(json.out);
    ASSERT_TRUE(doc.at("metadata").at("soundFile").is_string()) << input;
    const double duration = doc.at("metadata").at("duration").get<double>();
    EXPECT_DOUBLE_EQ(duration, last.start) << input;
    const auto& cues = doc.at("mouthCues");
    ASSERT_EQ(cues.size(), from_tsv.size()) << input;
    for (std::size_t i = 0; i < cues.size(); ++i) {
      // Same cues as the TSV; each ends where the next starts, the last at the duration.
      EXPECT_DOUBLE_EQ(cues[i].at("start").get<double>(), from_tsv[i].start) << input << " cue " << i;
      EXPECT_DOUBLE_EQ(cues[i].at("end").get<double>(), from_tsv[i].end) << input << " cue " << i;
      EXPECT_EQ(cues[i].at("value").get<std::string>(), from_tsv[i].shape) << input << " cue " << i;
    }
    // The bilabials of real speech show as closed mouths.
    EXPECT_NE(tsv.out.find("\tA\n"), std::string::npos) << input;
  }
}

TEST_F(CliTest, RhubarbFormatsDefaultToRhubarbsTenMillisecondCuesAndTheOthersTo30Fps) {
  const std::string path = (fs::path(LIPSYNC_TEST_DATA_DIR) / "closures" / "flite_4.psdur").string();
  for (const char* format : {"rhubarb-tsv", "rhubarb-json"}) {
    const RunResult by_default = run({"render", path, "--format", format});
    const RunResult at_100 = run({"render", path, "--format", format, "--fps", "100"});
    const RunResult at_30 = run({"render", path, "--format", format, "--fps", "30"});
    ASSERT_EQ(by_default.status, 0) << describe(by_default);
    EXPECT_EQ(by_default.out, at_100.out) << format;
    EXPECT_NE(by_default.out, at_30.out) << format << ": --fps must still choose the grid";
  }
  const RunResult oculus = run({"render", path, "--format", "visemes-oculus"});
  ASSERT_EQ(oculus.status, 0) << describe(oculus);
  EXPECT_EQ(nlohmann::json::parse(oculus.out).at("fps"), 30);
  const RunResult help = run({"render", "--help"});
  EXPECT_THAT(help.out, HasSubstr("(default: " + std::to_string(kFpsSetting.default_value) + "; " +
                                  std::to_string(kRhubarbCueFps) + " for the rhubarb formats"));
}

TEST_F(CliTest, RhubarbWithoutExtendedShapesUsesTheSixBasicOnes) {
  const std::string path = (fs::path(LIPSYNC_TEST_DATA_DIR) / "closures" / "festival_3.lab").string();
  const RunResult full = run({"render", path, "--format", "rhubarb-tsv"});
  const RunResult basic = run({"render", path, "--format", "rhubarb-tsv", "--extended-shapes", ""});
  ASSERT_EQ(full.status, 0) << describe(full);
  ASSERT_EQ(basic.status, 0) << describe(basic);
  std::set<std::string> full_shapes, basic_shapes;
  for (const auto& cue : read_rhubarb_tsv(full.out)) full_shapes.insert(cue.shape);
  for (const auto& cue : read_rhubarb_tsv(basic.out)) basic_shapes.insert(cue.shape);
  EXPECT_TRUE(full_shapes.count("X") && full_shapes.count("G")) << full.out;
  EXPECT_EQ(basic_shapes.count("G") + basic_shapes.count("H") + basic_shapes.count("X"), 0U) << basic.out;
  EXPECT_THAT(basic.out, ::testing::EndsWith("\tA\n"));  // Rhubarb ends on A without X

  const RunResult wrong = run({"render", path, "--format", "rhubarb-tsv", "--extended-shapes", "GQ"});
  EXPECT_EQ(wrong.status, 2);
  EXPECT_THAT(wrong.err, HasSubstr("--extended-shapes: 'GQ'"));
  const RunResult not_rhubarb = run({"render", path, "--format", "visemes-oculus", "--extended-shapes", "G"});
  EXPECT_EQ(not_rhubarb.status, 2);
  EXPECT_THAT(not_rhubarb.err, HasSubstr("--extended-shapes needs --format rhubarb-tsv or rhubarb-json"));
}

TEST_F(CliTest, VisemeFormatsStreamEqualsBatchByteForByte) {
  for (const char* input : {"festival_5.lab"}) {
    const std::string path = (fs::path(LIPSYNC_TEST_DATA_DIR) / "closures" / input).string();
    for (const char* format : {"visemes-oculus", "visemes-azure", "visemes-polly", "rhubarb-tsv", "rhubarb-json"}) {
      for (const char* fps : {"24"}) {
        std::vector<std::string> args = {"render", path, "--format", format, "--fps", fps};
        const RunResult offline = run(args);
        args.push_back("--incremental");
        const RunResult incremental = run(args);
        const std::string label = std::string(input) + " " + format + " at " + fps + " fps";
        ASSERT_EQ(offline.status, 0) << label << "\n" << describe(offline);
        ASSERT_EQ(incremental.status, 0) << label << "\n" << describe(incremental);
        EXPECT_FALSE(offline.out.empty()) << label;
        EXPECT_TRUE(offline.out == incremental.out) << label << ": incremental output differs";
      }
    }
  }
}

TEST_F(CliTest, OculusAndAzureVisemesCarryWeightsPerFrameAndExactEventTimes) {
  const std::string path = (fs::path(LIPSYNC_TEST_DATA_DIR) / "closures" / "flite_1.psdur").string();
  const RunResult azure = run({"render", path, "--format", "visemes-azure"});
  ASSERT_EQ(azure.status, 0) << describe(azure);
  const nlohmann::json doc = nlohmann::json::parse(azure.out);
  EXPECT_EQ(doc.at("format"), "lipsync-visemes");
  EXPECT_EQ(doc.at("vocabulary"), "azure");
  ASSERT_EQ(doc.at("visemes").size(), 22U);
  const auto& frames = doc.at("frames");
  ASSERT_GT(frames.size(), 30U);
  for (const auto& frame : frames) {
    ASSERT_EQ(frame.at("weights").size(), 22U);
    double sum = 0;
    for (const auto& w : frame.at("weights")) sum += w.get<double>();
    EXPECT_NEAR(sum, 1.0, 1e-5) << frame.at("t_us");
  }
  std::set<std::int64_t> frame_times;
  for (const auto& frame : frames) frame_times.insert(frame.at("t_us").get<std::int64_t>());
  for (const auto& event : doc.at("events")) {
    const auto start_us = event.at("start_us").get<std::int64_t>();
    EXPECT_TRUE(frame_times.count(start_us)) << "event at " << start_us << " is not at a frame";
    EXPECT_EQ(event.at("audio_offset_ticks").get<std::int64_t>(), 10 * start_us);  // Azure's 100-ns ticks
  }
  const RunResult polly = run({"render", path, "--format", "visemes-polly"});
  ASSERT_EQ(polly.status, 0) << describe(polly);
  std::istringstream lines(polly.out);
  // Polly's vocabulary groups phonemes differently, so its events are its own; each starts at a
  // frame, in whole milliseconds (rounded half up).
  std::set<std::int64_t> frame_times_ms;
  for (const std::int64_t t_us : frame_times) frame_times_ms.insert((t_us + 500) / 1000);
  std::size_t marks = 0;
  for (std::string line; std::getline(lines, line); ++marks) {
    const nlohmann::json mark = nlohmann::json::parse(line);  // Polly speech marks: one JSON object per line
    EXPECT_EQ(mark.at("type"), "viseme");
    ASSERT_TRUE(mark.at("time").is_number_integer()) << line;
    EXPECT_TRUE(frame_times_ms.count(mark.at("time").get<std::int64_t>())) << "mark at a time with no frame: " << line;
  }
  EXPECT_GT(marks, 10U);
}

TEST_F(CliTest, PhoneSetCanBeForced) {
  // bump_map.json declares arpabet; forcing radio makes its upper-case stressed
  // labels unknown (radio has no "AH1"), which proves the option is used.
  const RunResult forced = run({"render", fixture("bump_map.json"), "--phone-set", "radio"});
  EXPECT_EQ(forced.status, 1) << describe(forced);
  EXPECT_THAT(forced.err, HasSubstr("radio"));
  const RunResult detected = run({"render", fixture("bump_map.psdur"), "--phone-set", "auto"});
  EXPECT_EQ(detected.status, 0) << describe(detected);
}

// ---------------------------------------------------------------------------
// Errors: status, one-line message naming the culprit, and no file left behind

struct ErrorCase {
  std::vector<std::string> args;
  int status;
  std::vector<std::string> message_parts;
};

TEST_F(CliTest, ErrorsNameTheCulpritAndLeaveNoFile) {
  const std::vector<ErrorCase> cases = {
      {{"render", fixture("unknown_label.json")}, 1, {"unknown_label.json:3", "'XQ'", "arpabet"}},
      {{"render", fixture("overlap.json")}, 1, {"overlap.json:2", "0.250000"}},
      {{"render", fixture("bad_time.lab")}, 1, {"bad_time.lab:5", "0.24x000"}},
      {{"render", fixture("missing.json")}, 1, {"missing.json", "No such file or directory"}},
      {{"render", kFixtures.string()}, 1, {"Is a directory"}},
      {{"render", fixture("hello.json"), "--model", fixture("bad_model.json")}, 1, {"bad_model.json: ", "aa"}},
      {{"render", fixture("hello.json"), "--model", fixture("no_model.json")}, 1, {"no_model.json", "No such file"}},
      {{"render", fixture("hello.json"), "--fps", "30x"}, 2, {"--fps", "'30x'"}},
      {{"render", fixture("hello.json"), "--fps", "0"}, 2, {"--fps", "'0'", "1 to 240"}},
      {{"render", fixture("hello.json"), "--fps", "241"}, 2, {"--fps", "'241'"}},
      {{"render", fixture("hello.json"), "--fps", "99999999999999999999"}, 2, {"--fps"}},
      {{"render", fixture("hello.json"), "--fps"}, 2, {"--fps", "needs a value"}},
      {{"render", fixture("hello.json"), "--frobnicate"}, 2, {"'--frobnicate'"}},
      {{"render", fixture("hello.json"), "-x"}, 2, {"'-x'"}},
      {{"render", fixture("hello.json"), "--fixed-rate=yes"}, 2, {"--fixed-rate", "takes no value"}},
      {{"render", fixture("hello.json"), "--lookahead", "8"}, 2, {"--lookahead", "'8'", "0 to 7"}},
      {{"render", fixture("hello.json"), "--closure-fraction", "1"}, 2, {"--closure-fraction", "'1'"}},
      {{"render", fixture("hello.json"), "--closure-fraction", "0.5.1"}, 2, {"--closure-fraction", "'0.5.1'"}},
      {{"render", fixture("hello.json"), "--closure-fraction", "nan"}, 2, {"--closure-fraction", "'nan'"}},
      {{"render", fixture("hello.json"), "--sample-rate", "0"}, 2, {"--sample-rate", "'0'"}},
      {{"render", fixture("hello.json"), "--format", "xml"}, 2, {"--format", "'xml'"}},
      {{"render", fixture("hello.json"), "--input-format", "wav"}, 2, {"--input-format", "'wav'"}},
      {{"render", fixture("hello.json"), "--phone-set", "klingon"}, 2, {"--phone-set", "'klingon'", "arpabet"}},
      {{"render"}, 2, {"INPUT"}},
      {{"render", fixture("hello.json"), fixture("hello.json")}, 2, {"one INPUT"}},
      {{"demo", "--fps", "-3"}, 2, {"--fps", "'-3'"}},
  };
  for (const ErrorCase& error_case : cases) {
    std::vector<std::string> args = error_case.args;
    args.insert(args.end(), {"-o", "out.json"});
    std::string label;
    for (const auto& arg : args) label += arg + " ";
    const RunResult result = run(args);
    EXPECT_EQ(result.status, error_case.status) << label << "\n" << describe(result);
    EXPECT_THAT(result.err, StartsWith("lipsync: error: ")) << label;
    EXPECT_EQ(std::count(result.err.begin(), result.err.end(), '\n'), 1) << label << "\n" << result.err;
    for (const std::string& part : error_case.message_parts) EXPECT_THAT(result.err, HasSubstr(part)) << label;
    EXPECT_TRUE(result.out.empty()) << label;
    EXPECT_TRUE(listing().empty()) << label << ": left a file behind";
  }
}

TEST_F(CliTest, AFailedRenderKeepsThePreviousOutput) {
  write_text(dir_ / "out.json", "previous track");
  const RunResult result = run({"render", fixture("overlap.json"), "-o", "out.json"});
  EXPECT_EQ(result.status, 1);
  EXPECT_EQ(listing(), std::vector<std::string>{"out.json"});
  EXPECT_EQ(read_text(dir_ / "out.json"), "previous track");

  const RunResult success = run({"render", fixture("hello.json"), "-o", "out.json"});
  ASSERT_EQ(success.status, 0) << describe(success);
  EXPECT_EQ(listing(), std::vector<std::string>{"out.json"});
  EXPECT_TRUE(nlohmann::json::accept(read_text(dir_ / "out.json")));
}

TEST_F(CliTest, UnwritableOutputIsAnErrorNamingIt) {
  const RunResult missing_dir = run({"render", fixture("hello.json"), "-o", "no/such/dir/out.json"});
  EXPECT_EQ(missing_dir.status, 1);
  EXPECT_THAT(missing_dir.err, HasSubstr("'no/such/dir/out.json'"));
  fs::create_directory(dir_ / "sub");
  const RunResult is_dir = run({"render", fixture("hello.json"), "-o", "sub"});
  EXPECT_EQ(is_dir.status, 1);
  EXPECT_THAT(is_dir.err, HasSubstr("'sub'"));
  EXPECT_EQ(listing(), std::vector<std::string>{"sub"});
  EXPECT_TRUE(listing(dir_ / "sub").empty());
}

TEST_F(CliTest, AnOutputThatIsNotARegularFileIsWrittenIntoNotReplaced) {
  // `-o /dev/null`, a named pipe, a terminal: the track goes into it, and it stays what it was (a
  // temporary file renamed over /dev/null would replace the device). Shown with a named pipe.
  // The test holds the pipe open both ways (so that neither side waits for the other) with room
  // for the whole track, and reads what came once the command is done.
  const fs::path pipe = dir_ / "track.pipe";
  ASSERT_EQ(::mkfifo(pipe.c_str(), 0600), 0);
  const int fd = ::open(pipe.c_str(), O_RDWR | O_NONBLOCK);
  ASSERT_GE(fd, 0);
  ASSERT_GE(::fcntl(fd, F_SETPIPE_SZ, 1 << 20), 1 << 20);
  const RunResult written = run({"render", fixture("hello.json"), "-o", "track.pipe"});
  std::string piped;
  char buffer[4096];
  for (ssize_t n; (n = ::read(fd, buffer, sizeof buffer)) > 0;) piped.append(buffer, static_cast<std::size_t>(n));
  ::close(fd);
  ASSERT_EQ(written.status, 0) << describe(written);
  const RunResult to_stdout = run({"render", fixture("hello.json")});
  ASSERT_EQ(to_stdout.status, 0) << describe(to_stdout);
  EXPECT_EQ(piped, to_stdout.out);
  EXPECT_TRUE(fs::is_fifo(pipe));
  EXPECT_EQ(listing(), std::vector<std::string>{"track.pipe"});
}

// ---------------------------------------------------------------------------
// model dump, phone-sets

TEST_F(CliTest, ModelDumpReloads) {
  const RunResult result = run({"model", "dump"});
  ASSERT_EQ(result.status, 0) << describe(result);
  const ArticulationModel model = ArticulationModel::from_json(result.out, "dump");
  EXPECT_EQ(model.name(), ArticulationModel::builtin().name());
  EXPECT_EQ(model.channel_count(), ArticulationModel::builtin().channel_count());

  write_text(dir_ / "mine.json", result.out);
  const RunResult again = run({"model", "dump", "--model", "mine.json"});
  ASSERT_EQ(again.status, 0) << describe(again);
  EXPECT_EQ(again.out, result.out);

  const RunResult render = run({"render", fixture("hello.json"), "--model", "mine.json"});
  const RunResult builtin = run({"render", fixture("hello.json")});
  ASSERT_EQ(render.status, 0) << describe(render);
  EXPECT_EQ(render.out, builtin.out);
}

TEST_F(CliTest, ModelErrors) {
  EXPECT_EQ(run({"model"}).status, 2);
  EXPECT_EQ(run({"model", "show"}).status, 2);
  const RunResult bad = run({"model", "dump", "--model", fixture("bad_model.json")});
  EXPECT_EQ(bad.status, 1);
  EXPECT_THAT(bad.err, StartsWith("lipsync: error: " + fixture("bad_model.json") + ": "));
  EXPECT_TRUE(bad.out.empty());
}

TEST_F(CliTest, PhoneSetsListsEveryBuiltinSet) {
  const RunResult result = run({"phone-sets"});
  ASSERT_EQ(result.status, 0) << describe(result);
  // One entry per set: "name  description", the description wrapped onto
  // indented continuation lines.
  std::vector<std::string> entries;
  std::istringstream text(result.out);
  for (std::string line; std::getline(text, line);) {
    if (!line.empty() && line[0] != ' ') {
      entries.push_back(line);
    } else if (!entries.empty()) {
      entries.back() += " " + line.substr(line.find_first_not_of(' '));
    }
  }
  const std::vector<PhoneSet> sets = PhoneSet::builtin_all(ArticulationModel::builtin());
  ASSERT_EQ(entries.size(), sets.size() + 1) << result.out;
  for (std::size_t i = 0; i < sets.size(); ++i) {
    const std::string& name = sets[i].name();
    ASSERT_THAT(entries[i], StartsWith(name + "  "));
    std::string description = entries[i].substr(entries[i].find_first_not_of(' ', name.size()));
    EXPECT_EQ(description, sets[i].description()) << name;
  }
  EXPECT_THAT(entries.back(), StartsWith("auto  "));
}

TEST_F(CliTest, TextGridLabelOfSeveralPhonesIsAnErrorNamingItsFileAndTextLine) {
  // `qqzz` was read as four phonemes in one interval, exit 0. Its line is that of `text =`, not `xmin =`.
  testing::write_text(dir_ / "qq.TextGrid", three_phone_grid("qqzz"));
  RunResult result = run({"render", "qq.TextGrid", "-o", "t.json"});
  EXPECT_EQ(result.status, 1) << describe(result);
  EXPECT_THAT(result.err, StartsWith("lipsync: error: qq.TextGrid:22: phoneme 'qqzz': "));
  result = run({"render", "qq.TextGrid", "--phone-set", "ipa", "-o", "t.json"});
  EXPECT_EQ(result.status, 1) << describe(result);
  EXPECT_EQ(result.err,
            "lipsync: error: qq.TextGrid:22: phoneme 'qqzz': several phones in one interval (q q z z in phone set "
            "'ipa'), with no tie bar and no vowel: an interval holds one phone (mark an affricate with a "
            "tie bar, t͡s)\n");
  EXPECT_EQ(listing(), std::vector<std::string>{"qq.TextGrid"});
  // One phone in IPA renders: an affricate, a diphthong.
  for (const char* one_phone : {"pɸ", "eu", "t͡s"}) {
    testing::write_text(dir_ / "one.TextGrid", three_phone_grid(one_phone));
    EXPECT_EQ(run({"render", "one.TextGrid", "--phone-set", "ipa", "-o", "t.json"}).status, 0) << one_phone;
  }
}

}  // namespace
}  // namespace lipsync
