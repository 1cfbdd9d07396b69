// `lipsync say`, `lipsync align` and `lipsync render SPEECH.wav` from the outside:
// the real binary in a fresh directory, its exit status, messages and files
// (the video's streams through ffprobe, when installed).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "../support/child_process.hpp"
#include "lipsync/speech/audio.hpp"

namespace lipsync {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::RunResult;

class SpeechCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::make_temp_dir("lipsync-speech-cli-test-");
    capture_ = testing::make_temp_dir("lipsync-speech-cli-capture-");
  }
  void TearDown() override {
    fs::remove_all(dir_);
    fs::remove_all(capture_);
  }
  RunResult run(std::vector<std::string> args) {
    args.insert(args.begin(), LIPSYNC_CLI_BINARY);
    return testing::run_program(std::move(args), dir_, capture_);
  }
  std::vector<std::string> listing() const {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir_)) names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }
  std::int64_t wav_duration_us(const std::string& name) const {
    const std::string bytes = testing::read_text(dir_ / name);
    return speech::wav_layout_and_duration_us(bytes, name).second;
  }
  fs::path dir_, capture_;
};

bool have_ffprobe() { return ::access("/usr/bin/ffprobe", X_OK) == 0 && ::access("/usr/bin/ffmpeg", X_OK) == 0; }

TEST_F(SpeechCliTest, say_writes_the_speech_and_a_track_that_covers_it) {
  const RunResult result = run({"say", "Papa parked the car.", "-o", "track.json", "--wav", "speech.wav"});
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_EQ(listing(), (std::vector<std::string>{"speech.wav", "track.json"}));
  const auto track = nlohmann::json::parse(testing::read_text(dir_ / "track.json"));
  const std::int64_t last_us = track["frames"].back()["t_us"];
  const std::int64_t audio_us = wav_duration_us("speech.wav");
  EXPECT_GT(audio_us, 1'000'000);
  EXPECT_GE(last_us, audio_us);
  EXPECT_LE(last_us, audio_us + 1'000'000 / 30 + 1);
}

TEST_F(SpeechCliTest, say_video_has_audio_and_video_of_equal_length) {
  if (!have_ffprobe()) GTEST_SKIP() << "ffmpeg/ffprobe not installed";
  const RunResult result = run({"say", "Papa parked the car.", "--video", "face.mp4", "--mesh-subdivision", "0"});
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_EQ(listing(), std::vector<std::string>{"face.mp4"});  // the temporary WAV is gone
  const RunResult probe = testing::run_program(
      {"/usr/bin/ffprobe", "-v", "error", "-show_streams", "-of", "json", (dir_ / "face.mp4").string()}, dir_,
      capture_);
  ASSERT_EQ(probe.status, 0) << probe.err;
  const auto streams = nlohmann::json::parse(probe.out)["streams"];
  ASSERT_EQ(streams.size(), 2U);
  std::optional<double> video_s, audio_s;
  for (const auto& stream : streams) {
    (stream["codec_type"] == "video" ? video_s : audio_s) = std::stod(stream["duration"].get<std::string>());
  }
  ASSERT_TRUE(video_s && audio_s);
  EXPECT_GT(*audio_s, 1.0);
  EXPECT_NEAR(*video_s, *audio_s, 1.0 / 30);
}

TEST_F(SpeechCliTest, align_writes_a_textgrid_that_render_reads_back) {
  ASSERT_EQ(run({"say", "Papa parked the car.", "--wav", "speech.wav", "-o", "say.json"}).status, 0);
  const RunResult aligned = run({"align", "speech.wav", "--text", "Papa parked the car.", "-o", "speech.TextGrid"});
  ASSERT_EQ(aligned.status, 0) << aligned.err;
  EXPECT_EQ(aligned.err, "lipsync: note: speech.wav: resampled from 22050 Hz to 16000 Hz\n");
  const std::string grid = testing::read_text(dir_ / "speech.TextGrid");
  EXPECT_THAT(grid, HasSubstr("name = \"words\""));
  EXPECT_THAT(grid, HasSubstr("text = \"parked\""));
  const RunResult rendered = run({"render", "speech.TextGrid", "-o", "from_grid.json"});
  ASSERT_EQ(rendered.status, 0) << rendered.err;
  // render SPEECH.wav --text-file aligns the same way and then renders: the same frame times,
  // then frames up to the end of the audio. (Values differ in the last 7 segments' reach, where
  // the silence that extends the track to the audio's end enters the coarticulation window.)
  testing::write_text(dir_ / "words.txt", "Papa parked the car.\n");
  const RunResult direct = run({"render", "speech.wav", "--text-file", "words.txt", "-o", "from_wav.json"});
  ASSERT_EQ(direct.status, 0) << direct.err;
  const auto from_grid = nlohmann::json::parse(testing::read_text(dir_ / "from_grid.json"))["frames"];
  const auto from_wav = nlohmann::json::parse(testing::read_text(dir_ / "from_wav.json"))["frames"];
  ASSERT_GE(from_wav.size(), from_grid.size());
  for (std::size_t i = 0; i + 1 < from_grid.size(); ++i) {
    EXPECT_EQ(from_wav[i]["t_us"], from_grid[i]["t_us"]) << "frame " << i;
    EXPECT_EQ(from_wav[i]["kind"], from_grid[i]["kind"]) << "frame " << i;
  }
  for (std::size_t i = 0; i < 10; ++i) EXPECT_EQ(from_wav[i], from_grid[i]) << "frame " << i;
  EXPECT_GE(from_wav.back()["t_us"].get<std::int64_t>(), wav_duration_us("speech.wav"));
}

TEST_F(SpeechCliTest, bad_input_exits_1_naming_the_file) {
  testing::write_text(dir_ / "notes.wav", "these are not samples");
  RunResult result = run({"align", "notes.wav", "-o", "out.TextGrid"});
  EXPECT_EQ(result.status, 1);
  EXPECT_EQ(result.err, "lipsync: error: notes.wav: not a WAV file (expected a RIFF/WAVE header, found 'thes')\n");
  result = run({"align", "missing.wav"});
  EXPECT_EQ(result.status, 1);
  EXPECT_THAT(result.err, HasSubstr("missing.wav"));
  result = run({"say", "Hello.", "--voice", "no-such-voice", "-o", "t.json"});
  EXPECT_EQ(result.status, 1);
  EXPECT_EQ(result.err, "lipsync: error: espeak-ng: unknown voice 'no-such-voice' (see 'espeak-ng --voices')\n");
  EXPECT_EQ(listing(), std::vector<std::string>{"notes.wav"});
}

TEST_F(SpeechCliTest, a_ten_minute_recording_is_refused_quickly_naming_the_file) {
  // 600 s of a 16 kHz tone (19 MB, written here): refused before any decoding, in bounded time.
  speech::PcmAudio audio;
  audio.samples.resize(std::size_t(600) * 16000);
  for (std::size_t i = 0; i < audio.samples.size(); ++i)
    audio.samples[i] = static_cast<std::int16_t>((i / 40) % 2 ? 8000 : -8000);
  {
    std::ofstream out(dir_ / "long.wav", std::ios::binary);
    speech::write_wav(out, audio);
  }
  const auto start = std::chrono::steady_clock::now();
  const RunResult result = run({"render", "long.wav", "--text", "a very long reading", "-o", "track.json"});
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(result.status, 1);
  EXPECT_EQ(
      result.err,
      "lipsync: error: long.wav: 600.0 s of audio is longer than the 120 s an alignment accepts; split it at pauses\n");
  EXPECT_LT(seconds, 20.0) << "the refusal must not wait for a decode";
  EXPECT_EQ(listing(), std::vector<std::string>{"long.wav"});
}

TEST_F(SpeechCliTest, bad_command_lines_exit_2) {
  const std::vector<std::vector<std::string>> commands = {
      {"say"},
      {"say", "a", "b"},
      {"say", "Hello.", "--rate", "20"},
      {"say", "Hello.", "--wav", "-"},
      {"align"},
      {"align", "x.wav", "--text", "a", "--text-file", "b"},
      {"render", "x.lab", "--text"},
  };
  for (const auto& command : commands) {
    const RunResult result = run(command);
    EXPECT_EQ(result.status, 2) << command.front() << " " << (command.size() > 1 ? command[1] : "") << ": "
                                << result.err;
    EXPECT_THAT(result.err, HasSubstr("lipsync: error: "));
  }
  EXPECT_TRUE(listing().empty());
}

TEST_F(SpeechCliTest, help_documents_say_and_align) {
  RunResult result = run({"say", "--help"});
  ASSERT_EQ(result.status, 0);
  EXPECT_THAT(result.out, HasSubstr("Usage: lipsync say TEXT [options]"));
  EXPECT_THAT(result.out, HasSubstr("--voice NAME"));
  result = run({"align", "--help"});
  ASSERT_EQ(result.status, 0);
  EXPECT_THAT(result.out, HasSubstr("--text-file FILE"));
  EXPECT_THAT(result.out,
              HasSubstr("the starts and ends of /p b m f v/ then\nmove to where the sound shows the lips closing"));
  result = run({"--help"});
  EXPECT_THAT(result.out, HasSubstr("  say "));
  EXPECT_THAT(result.out, HasSubstr("  align "));
}

}  // namespace
}  // namespace lipsync
