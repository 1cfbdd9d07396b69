// Track writers: every format pinned on hand-built tracks and a tiny model, so
// that these tests depend on neither the renderer nor the default model. The
// writer over names and weights given as data (NamedTrackView) is compared with
// the model-based one byte for byte, the built-in model included.
#include "lipsync/track_writer.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/error.hpp"

namespace lipsync {
namespace {

using ::testing::ElementsAreArray;
using ::testing::HasSubstr;

// Three channels; each one drives a single ARKit shape. jawRight and mouthLeft
// sit at different positions in Apple's order and in Live Link Face's order,
// so a column bound by index instead of name shows up as a misplaced value.
constexpr std::string_view kTinyModel = R"({
  "format": "lipsync-articulation-model", "version": 1, "name": "tiny \"test\" model",
  "channels": [
    {"name": "jaw_rotation", "kind": "jaw", "min": 0, "max": 1, "rest": 0},
    {"name": "lip_side", "kind": "muscle", "min": 0, "max": 1, "rest": 0},
    {"name": "tongue_tip", "kind": "tongue", "min": -1, "max": 1, "rest": 0}
  ],
  "dominance_defaults": {},
  "phonemes": {"sil": {"class": "silence"}},
  "arkit": {
    "jawOpen": {"weights": {"jaw_rotation": 1.0}},
    "jawRight": {"weights": {"lip_side": 0.5}},
    "mouthLeft": {"weights": {"tongue_tip": 1.0}}
  }
})";

const ArticulationModel& tiny_model() {
  static const ArticulationModel model = ArticulationModel::from_json(kTinyModel, "tiny.json");
  return model;
}

struct Frame {
  std::int64_t t_us;
  FrameKind kind;
  std::vector<float> values;
};

Track make_track(const std::vector<Frame>& frames, int fps = 30) {
  Track track;
  track.channel_count = 3;
  track.fps = fps;
  for (const Frame& frame : frames) {
    track.t_us.push_back(frame.t_us);
    track.kinds.push_back(frame.kind);
    track.values.insert(track.values.end(), frame.values.begin(), frame.values.end());
  }
  return track;
}

std::string write(const Track& track, TrackFormat format, const ArticulationModel& model = tiny_model()) {
  std::ostringstream out;
  write_track(track, model, format, out);
  return out.str();
}

std::vector<std::string> split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(text);
  while (std::getline(in, part, separator)) parts.push_back(part);
  return parts;
}

std::vector<float> retargeted(const std::vector<float>& values) {
  std::vector<float> arkit(kArkitNames.size());
  tiny_model().retarget_to_arkit(values, arkit);
  return arkit;
}

const Track& sample_track() {
  static const Track track = make_track({
      {0, FrameKind::uniform, {0.0F, 0.0F, 0.0F}},
      {33'333, FrameKind::closure_start, {0.1F, 1.0F / 3.0F, -0.25F}},
      {50'000, FrameKind::closure_end, {1e-7F, 0.75F, 1.0F}},
      {66'667, FrameKind::short_segment, {1.0F, 2.0F / 3.0F, -1.0F}},
  });
  return track;
}

TEST(TrackFormatNames, RoundTrip) {
  for (auto format : {TrackFormat::json, TrackFormat::csv, TrackFormat::arkit_csv}) {
    EXPECT_EQ(track_format_from_string(to_string(format)), format);
  }
  EXPECT_EQ(to_string(TrackFormat::arkit_csv), "arkit-csv");
  EXPECT_EQ(track_format_from_string("arkit_csv"), std::nullopt);
  EXPECT_EQ(track_format_from_string("JSON"), std::nullopt);
}

TEST(JsonWriter, ParsesAndEveryFieldMatches) {
  const Track& track = sample_track();
  const auto doc = nlohmann::json::parse(write(track, TrackFormat::json));

  EXPECT_EQ(doc["format"], "lipsync-track");
  EXPECT_EQ(doc["version"], 1);
  EXPECT_EQ(doc["model"], "tiny \"test\" model");
  EXPECT_EQ(doc["fps"], 30);
  EXPECT_EQ(doc["channels"], nlohmann::json({"jaw_rotation", "lip_side", "tongue_tip"}));
  ASSERT_EQ(doc["arkit_names"].size(), 52U);
  for (std::size_t j = 0; j < kArkitNames.size(); ++j) {
    EXPECT_EQ(doc["arkit_names"][j].get<std::string>(), kArkitNames[j]) << "arkit_names[" << j << "]";
  }

  ASSERT_EQ(doc["frames"].size(), track.frame_count());
  for (std::size_t f = 0; f < track.frame_count(); ++f) {
    SCOPED_TRACE("frame " + std::to_string(f));
    const auto& frame = doc["frames"][f];
    EXPECT_EQ(frame.size(), 5U) << frame.dump();
    EXPECT_EQ(frame["t_us"].get<std::int64_t>(), track.t_us[f]);
    EXPECT_TRUE(frame["t"].is_number_float());
    EXPECT_DOUBLE_EQ(frame["t"].get<double>(), static_cast<double>(track.t_us[f]) * 1e-6);
    EXPECT_EQ(frame["kind"].get<std::string>(), to_string(track.kinds[f]));

    const auto values = track.frame_values(f);
    std::vector<float> parsed_values;
    for (const auto& v : frame["values"]) parsed_values.push_back(static_cast<float>(v.get<double>()));
    EXPECT_THAT(parsed_values, ElementsAreArray(values.begin(), values.end()));

    std::vector<float> parsed_arkit;
    for (const auto& v : frame["arkit"]) parsed_arkit.push_back(static_cast<float>(v.get<double>()));
    EXPECT_THAT(parsed_arkit, ElementsAreArray(retargeted({values.begin(), values.end()})));
  }
  EXPECT_EQ(static_cast<float>(doc["frames"][1]["arkit"][17].get<double>()), 0.1F) << "jawOpen follows jaw_rotation";
}

TEST(JsonWriter, TimesAreExactToTheMicrosecond) {
  const Track track = make_track({
      {1, FrameKind::uniform, {0, 0, 0}},
      {33'333, FrameKind::uniform, {0, 0, 0}},
      {3'600'000'001, FrameKind::uniform, {0, 0, 0}},
      {86'400'000'000, FrameKind::uniform, {0, 0, 0}},
  });
  const std::string text = write(track, TrackFormat::json);
  EXPECT_THAT(text, HasSubstr(R"({"t":0.000001,"t_us":1,)"));
  EXPECT_THAT(text, HasSubstr(R"({"t":0.033333,"t_us":33333,)"));
  EXPECT_THAT(text, HasSubstr(R"({"t":3600.000001,"t_us":3600000001,)"));
  EXPECT_THAT(text, HasSubstr(R"({"t":86400.000000,"t_us":86400000000,)"));
  const auto doc = nlohmann::json::parse(text);
  EXPECT_EQ(doc["frames"][2]["t_us"].get<std::int64_t>(), 3'600'000'001);
}

TEST(JsonWriter, FloatsUseTheShortestRoundTripText) {
  const Track track = make_track({{0, FrameKind::uniform, {0.1F, 1.0F / 3.0F, -0.0F}}});
  EXPECT_THAT(write(track, TrackFormat::json), HasSubstr(R"("values":[0.1,0.33333334,-0],)"));
}

TEST(JsonWriter, OneFramePerLine) {
  const std::vector<std::string> lines = split(write(sample_track(), TrackFormat::json), '\n');
  ASSERT_EQ(lines.size(), 5 + sample_track().frame_count());
  EXPECT_EQ(lines[0], R"({"format":"lipsync-track","version":1,"model":"tiny \"test\" model","fps":30,)");
  EXPECT_EQ(lines[1], R"("channels":["jaw_rotation","lip_side","tongue_tip"],)");
  EXPECT_THAT(lines[2], HasSubstr(R"("arkit_names":["eyeBlinkLeft",)"));
  EXPECT_THAT(lines[2], ::testing::EndsWith(R"("tongueOut"],)"));
  EXPECT_EQ(lines[3], R"("frames":[)");
  EXPECT_THAT(lines[4], ::testing::StartsWith(R"({"t":0.000000,"t_us":0,"kind":"uniform","values":[0,0,0],)"));
  EXPECT_THAT(lines[4], ::testing::EndsWith("]},"));
  EXPECT_THAT(lines[5], ::testing::StartsWith(R"({"t":0.033333,"t_us":33333,"kind":"closure_start",)"));
  EXPECT_THAT(lines[7], ::testing::EndsWith("]}"));
  EXPECT_EQ(lines.back(), "]}");
}

TEST(JsonWriter, EmptyTrackIsValid) {
  const auto doc = nlohmann::json::parse(write(make_track({}), TrackFormat::json));
  EXPECT_TRUE(doc["frames"].is_array());
  EXPECT_TRUE(doc["frames"].empty());
}

TEST(JsonWriter, LongTrackSurvivesBufferFlushes) {
  std::vector<Frame> frames;
  for (int i = 0; i < 5000; ++i) {
    const float v = static_cast<float>(i) / 4999.0F;
    frames.push_back({static_cast<std::int64_t>(i) * 33'333, FrameKind::uniform, {v, 1.0F - v, v - 0.5F}});
  }
  const Track track = make_track(frames);
  const auto doc = nlohmann::json::parse(write(track, TrackFormat::json));
  ASSERT_EQ(doc["frames"].size(), 5000U);
  std::vector<float> parsed;
  for (const auto& frame : doc["frames"]) {
    for (const auto& v : frame["values"]) parsed.push_back(static_cast<float>(v.get<double>()));
  }
  EXPECT_THAT(parsed, ElementsAreArray(track.values));
}

TEST(CsvWriter, HeaderAndRows) {
  EXPECT_EQ(write(sample_track(), TrackFormat::csv),
            "t,t_us,kind,jaw_rotation,lip_side,tongue_tip\n"
            "0.000000,0,uniform,0,0,0\n"
            "0.033333,33333,closure_start,0.1,0.33333334,-0.25\n"
            "0.050000,50000,closure_end,1e-07,0.75,1\n"
            "0.066667,66667,short_segment,1,0.6666667,-1\n");
}

TEST(CsvWriter, QuotesChannelNamesThatNeedIt) {
  std::string json(kTinyModel);
  json.replace(json.find("lip_side\", \"kind"), 8, "lip,\\\"side\\\"");
  json.replace(json.find("\"lip_side\": 0.5"), 10, "\"lip,\\\"side\\\"\"");
  const auto model = ArticulationModel::from_json(json, "quoted.json");
  const std::string text = write(make_track({}), TrackFormat::csv, model);
  EXPECT_EQ(text, "t,t_us,kind,jaw_rotation,\"lip,\"\"side\"\"\",tongue_tip\n");
}

// The header from docs/output-formats.md and the Live Link Face note, verbatim.
constexpr std::string_view kLiveLinkFaceHeader =
    "Timecode,BlendShapeCount,EyeBlinkLeft,EyeLookDownLeft,EyeLookInLeft,EyeLookOutLeft,EyeLookUpLeft,"
    "EyeSquintLeft,EyeWideLeft,EyeBlinkRight,EyeLookDownRight,EyeLookInRight,EyeLookOutRight,"
    "EyeLookUpRight,EyeSquintRight,EyeWideRight,JawForward,JawRight,JawLeft,JawOpen,MouthClose,"
    "MouthFunnel,MouthPucker,MouthRight,MouthLeft,MouthSmileLeft,MouthSmileRight,MouthFrownLeft,"
    "MouthFrownRight,MouthDimpleLeft,MouthDimpleRight,MouthStretchLeft,MouthStretchRight,"
    "MouthRollLower,MouthRollUpper,MouthShrugLower,MouthShrugUpper,MouthPressLeft,MouthPressRight,"
    "MouthLowerDownLeft,MouthLowerDownRight,MouthUpperUpLeft,MouthUpperUpRight,BrowDownLeft,"
    "BrowDownRight,BrowInnerUp,BrowOuterUpLeft,BrowOuterUpRight,CheekPuff,CheekSquintLeft,"
    "CheekSquintRight,NoseSneerLeft,NoseSneerRight,TongueOut,HeadYaw,HeadPitch,HeadRoll,LeftEyeYaw,"
    "LeftEyePitch,LeftEyeRoll,RightEyeYaw,RightEyePitch,RightEyeRoll";

TEST(LiveLinkFaceCsv, HeaderMatchesUnrealExactly) {
  const std::vector<std::string> lines = split(write(make_track({}), TrackFormat::arkit_csv), '\n');
  ASSERT_EQ(lines.size(), 1U);
  EXPECT_EQ(lines[0], kLiveLinkFaceHeader);
  EXPECT_EQ(split(lines[0], ',').size(), 63U);
}

TEST(LiveLinkFaceCsv, RowsHaveCount61AndZeroRotations) {
  const std::vector<std::string> lines = split(write(sample_track(), TrackFormat::arkit_csv), '\n');
  ASSERT_EQ(lines.size(), 1 + sample_track().frame_count());
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const std::vector<std::string> cells = split(lines[i], ',');
    ASSERT_EQ(cells.size(), 63U) << lines[i];
    EXPECT_EQ(cells[1], "61");
    EXPECT_THAT(std::vector<std::string>(cells.end() - 9, cells.end()),
                ElementsAreArray(std::vector<std::string>(9, "0")));
  }
}

TEST(LiveLinkFaceCsv, ValuesAreRoutedByName) {
  const Track track = make_track({{0, FrameKind::uniform, {0.25F, 0.5F, 0.75F}}});
  const std::vector<std::string> lines = split(write(track, TrackFormat::arkit_csv), '\n');
  ASSERT_EQ(lines.size(), 2U);
  const std::vector<std::string> header = split(lines[0], ',');
  const std::vector<std::string> cells = split(lines[1], ',');
  std::map<std::string, std::string> by_name;
  for (std::size_t i = 2; i < header.size(); ++i) by_name[header[i]] = cells[i];

  EXPECT_EQ(by_name["JawOpen"], "0.25");
  EXPECT_EQ(by_name["JawRight"], "0.25") << "lip_side × 0.5";
  EXPECT_EQ(by_name["MouthLeft"], "0.75");
  for (const auto& [name, value] : by_name) {
    if (name != "JawOpen" && name != "JawRight" && name != "MouthLeft") {
      EXPECT_EQ(value, "0") << name;
    }
  }
}

TEST(LiveLinkFaceCsv, EveryArkitShapeLandsInItsOwnColumn) {
  // One model per shape would be slow to write; instead drive all 52 shapes with
  // distinct weights of one channel and compare by name. mouthClose gets a weight below jawOpen's:
  // the retargeting caps it at jawOpen (model.hpp).
  const auto weight = [](std::size_t j) {
    return kArkitNames[j] == "mouthClose" ? 0.1F : static_cast<float>(j + 1) / 64.0F;
  };
  std::string arkit;
  for (std::size_t j = 0; j < kArkitNames.size(); ++j) {
    if (j > 0) arkit += ",";
    arkit += "\"" + std::string(kArkitNames[j]) +
             "\": {\"weights\": {\"jaw_rotation\": " + std::to_string(static_cast<double>(weight(j))) + "}}";
  }
  std::string json(kTinyModel);
  const auto begin = json.find("\"arkit\"");
  json.replace(begin, json.rfind('}') - begin, "\"arkit\": {" + arkit + "}\n");
  const auto model = ArticulationModel::from_json(json, "all-shapes.json");

  const Track track = make_track({{0, FrameKind::uniform, {1.0F, 0.0F, 0.0F}}});
  const std::vector<std::string> lines = split(write(track, TrackFormat::arkit_csv, model), '\n');
  const std::vector<std::string> header = split(lines[0], ',');
  const std::vector<std::string> cells = split(lines[1], ',');
  for (std::size_t j = 0; j < kArkitNames.size(); ++j) {
    std::string pascal(kArkitNames[j]);
    pascal[0] = static_cast<char>(pascal[0] - 'a' + 'A');
    const auto column = std::find(header.begin(), header.end(), pascal);
    ASSERT_NE(column, header.end()) << pascal;
    EXPECT_EQ(std::stof(cells[static_cast<std::size_t>(column - header.begin())]), weight(j)) << pascal;
  }
}

std::string timecode(std::int64_t t_us, int fps) {
  const Track track = make_track({{t_us, FrameKind::uniform, {0, 0, 0}}}, fps);
  const std::vector<std::string> lines = split(write(track, TrackFormat::arkit_csv), '\n');
  return split(lines.at(1), ',').at(0);
}

TEST(LiveLinkFaceCsv, TimecodeCountsFramesWithinTheSecond) {
  EXPECT_EQ(timecode(0, 30), "00:00:00:00.000");
  EXPECT_EQ(timecode(1'500'000, 30), "00:00:01:15.000");
  EXPECT_EQ(timecode(33'333, 30), "00:00:00:01.000") << "grid time rounded to the µs";
  EXPECT_EQ(timecode(966'667, 30), "00:00:00:29.000");
  EXPECT_EQ(timecode(50'000, 30), "00:00:00:01.500") << "key frame between grid points";
  EXPECT_EQ(timecode(1'010'000, 60), "00:00:01:00.600");
  EXPECT_EQ(timecode(999'999, 24), "00:00:01:00.000") << "rounding carries into the second";
  EXPECT_EQ(timecode(3'723'500'000, 30), "01:02:03:15.000");
  EXPECT_EQ(timecode(3'600'000'001, 60), "01:00:00:00.000");
  EXPECT_EQ(timecode(86'400'000'000, 240), "24:00:00:00.000");
  EXPECT_EQ(timecode(4'167, 240), "00:00:00:01.000");
}

TEST(WriteTrack, RejectsATrackOfAnotherModel) {
  Track track = make_track({{0, FrameKind::uniform, {0, 0, 0}}});
  track.channel_count = 2;
  track.values.resize(2);
  std::ostringstream out;
  EXPECT_THROW(write_track(track, tiny_model(), TrackFormat::json, out), std::invalid_argument);
}

TEST(WriteTrack, RejectsATrackWhoseArraysDisagree) {
  Track track = make_track({{0, FrameKind::uniform, {0, 0, 0}}});
  track.kinds.clear();
  std::ostringstream out;
  EXPECT_THROW(write_track(track, tiny_model(), TrackFormat::csv, out), std::invalid_argument);
}

/// A track of `model` with `frame_count` frames of values in each channel's range,
/// from a fixed seed, mixing every frame kind.
Track random_track(const ArticulationModel& model, std::size_t frame_count) {
  std::mt19937 random(20240611);
  Track track;
  track.channel_count = model.channel_count();
  for (std::size_t f = 0; f < frame_count; ++f) {
    track.t_us.push_back(static_cast<std::int64_t>(f) * 25'000 + static_cast<std::int64_t>(random() % 1000));
    track.kinds.push_back(static_cast<FrameKind>(random() % 4));
    for (const ChannelSpec& channel : model.channels()) {
      std::uniform_real_distribution<float> value(static_cast<float>(channel.min), static_cast<float>(channel.max));
      track.values.push_back(value(random));
    }
  }
  return track;
}

/// The view of `track` that the model-based writer builds: the model's names, its retargeting.
struct ModelNames {
  std::vector<std::string_view> channels;
  std::vector<float> arkit;
};

ModelNames model_names(const Track& track, const ArticulationModel& model) {
  ModelNames names;
  for (const ChannelSpec& channel : model.channels()) names.channels.emplace_back(channel.name);
  names.arkit.resize(track.frame_count() * kArkitNames.size());
  for (std::size_t f = 0; f < track.frame_count(); ++f) {
    model.retarget_to_arkit(track.frame_values(f),
                            std::span<float>(names.arkit).subspan(f * kArkitNames.size(), kArkitNames.size()));
  }
  return names;
}

std::string write(const NamedTrackView& view, TrackFormat format) {
  std::ostringstream out;
  write_track(view, format, out);
  return out.str();
}

TEST(NamedTrackWriter, NamesAndWeightsAsDataWriteTheBytesOfTheModelWriter) {
  for (const ArticulationModel* model : {&ArticulationModel::builtin(), &tiny_model()}) {
    // Long enough for several 64 KiB flushes in every format.
    const Track track = random_track(*model, 3000);
    const ModelNames names = model_names(track, *model);
    const NamedTrackView view{.model = model->name(),
                              .channel_names = names.channels,
                              .arkit_names = kArkitNames,
                              .track = track,
                              .arkit = names.arkit};
    for (auto format : {TrackFormat::json, TrackFormat::csv, TrackFormat::arkit_csv}) {
      SCOPED_TRACE(model->name() + " " + std::string(to_string(format)));
      const std::string expected = write(track, format, *model);
      EXPECT_GT(expected.size(), 64U * 1024U);
      EXPECT_TRUE(write(view, format) == expected) << "the two writers differ";
    }
  }
}

TEST(NamedTrackWriter, CustomNamesAppearInTheHeaderAndColumns) {
  const Track track = make_track({
      {0, FrameKind::uniform, {0.25F, 0.5F, 0.75F}},
      {40'000, FrameKind::closure_start, {1.0F, 0.0F, -1.0F}},
  });
  const std::vector<std::string_view> channels = {"lower,lip", "corner \"L\"", "tongue"};
  // Two shapes only, in neither Apple's nor Live Link Face's order.
  const std::vector<std::string_view> arkit_names = {"mouthLeft", "jawOpen"};
  const std::vector<float> arkit = {0.125F, 0.5F, 0.0F, 1.0F};
  const NamedTrackView view{
      .model = "server model", .channel_names = channels, .arkit_names = arkit_names, .track = track, .arkit = arkit};

  const auto doc = nlohmann::json::parse(write(view, TrackFormat::json));
  EXPECT_EQ(doc["model"], "server model");
  EXPECT_EQ(doc["channels"], nlohmann::json({"lower,lip", "corner \"L\"", "tongue"}));
  EXPECT_EQ(doc["arkit_names"], nlohmann::json({"mouthLeft", "jawOpen"}));
  EXPECT_EQ(doc["frames"][0]["arkit"], nlohmann::json({0.125, 0.5}));
  EXPECT_EQ(doc["frames"][1]["arkit"], nlohmann::json({0.0, 1.0}));
  EXPECT_EQ(doc["frames"][1]["values"], nlohmann::json({1.0, 0.0, -1.0}));

  EXPECT_EQ(write(view, TrackFormat::csv),
            "t,t_us,kind,\"lower,lip\",\"corner \"\"L\"\"\",tongue\n"
            "0.000000,0,uniform,0.25,0.5,0.75\n"
            "0.040000,40000,closure_start,1,0,-1\n");

  const std::vector<std::string> lines = split(write(view, TrackFormat::arkit_csv), '\n');
  ASSERT_EQ(lines.size(), 3U);
  EXPECT_EQ(lines[0], kLiveLinkFaceHeader);
  const std::vector<std::string> header = split(lines[0], ',');
  for (std::size_t f = 0; f < 2; ++f) {
    const std::vector<std::string> cells = split(lines[1 + f], ',');
    ASSERT_EQ(cells.size(), header.size());
    std::map<std::string, std::string> by_name;
    for (std::size_t i = 2; i < header.size(); ++i) by_name[header[i]] = cells[i];
    EXPECT_EQ(std::stof(by_name["MouthLeft"]), arkit[2 * f]) << "frame " << f;
    EXPECT_EQ(std::stof(by_name["JawOpen"]), arkit[2 * f + 1]) << "frame " << f;
    for (const auto& [name, value] : by_name) {
      if (name != "MouthLeft" && name != "JawOpen") {
        EXPECT_EQ(value, "0") << name << ", frame " << f;
      }
    }
  }
}

TEST(NamedTrackWriter, WithoutArkitWeightsJsonHasEmptyArraysAndArkitCsvRefuses) {
  const Track track = make_track({{0, FrameKind::uniform, {0.25F, 0.5F, 0.75F}}});
  const std::vector<std::string_view> channels = {"a", "b", "c"};
  const NamedTrackView view{.model = "m", .channel_names = channels, .track = track};
  const auto doc = nlohmann::json::parse(write(view, TrackFormat::json));
  EXPECT_TRUE(doc["arkit_names"].empty());
  EXPECT_TRUE(doc["frames"][0]["arkit"].empty());
  std::ostringstream out;
  EXPECT_THROW(write_track(view, TrackFormat::arkit_csv, out), std::invalid_argument);
}

TEST(NamedTrackWriter, RejectsNamesOrWeightsThatDoNotFitTheTrack) {
  const Track track = make_track({{0, FrameKind::uniform, {0.25F, 0.5F, 0.75F}}});
  const std::vector<std::string_view> two_channels = {"a", "b"};
  const std::vector<std::string_view> three_channels = {"a", "b", "c"};
  const std::vector<std::string_view> arkit_names = {"jawOpen"};
  const std::vector<float> two_weights = {0.5F, 0.5F};
  std::ostringstream out;
  EXPECT_THROW(
      write_track(NamedTrackView{.model = "m", .channel_names = two_channels, .track = track}, TrackFormat::csv, out),
      std::invalid_argument);
  EXPECT_THROW(write_track(NamedTrackView{.model = "m",
                                          .channel_names = three_channels,
                                          .arkit_names = arkit_names,
                                          .track = track,
                                          .arkit = two_weights},
                           TrackFormat::json, out),
               std::invalid_argument);
}

}  // namespace
}  // namespace lipsync
