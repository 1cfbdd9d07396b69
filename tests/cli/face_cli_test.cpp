// End-to-end tests of the face outputs of `lipsync render` (--mesh, --video, --audio, --still):
// the real binary runs in a fresh temporary directory; the files it leaves are checked from the
// outside (the glTF header, and ffprobe's view of the video's streams, duration and frame count).
// The video tests are skipped when ffmpeg/ffprobe are not installed (deploy/install-deps.sh
// installs them); the missing-ffmpeg error is tested with an empty PATH.
#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "../support/child_process.hpp"
#include "../support/lipsync_cli_test.hpp"

namespace lipsync {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using testing::make_temp_dir;
using testing::read_text;
using testing::run_program;
using testing::RunOptions;
using testing::RunResult;

const fs::path kFixtures = fs::path(LIPSYNC_TEST_DATA_DIR) / "cli";

std::optional<std::string> find_program(const std::string& name) {
  for (const char* dir : {"/usr/bin", "/usr/local/bin", "/bin"}) {
    const fs::path candidate = fs::path(dir) / name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return std::nullopt;
}

// One second of a 220 Hz tone, 16 kHz mono 16-bit PCM.
void write_wav(const fs::path& path, double seconds) {
  const std::uint32_t rate = 16000, samples = static_cast<std::uint32_t>(seconds * rate);
  std::ofstream out(path, std::ios::binary);
  const auto u32 = [&](std::uint32_t v) { out.write(reinterpret_cast<const char*>(&v), 4); };
  const auto u16 = [&](std::uint16_t v) { out.write(reinterpret_cast<const char*>(&v), 2); };
  out << "RIFF";
  u32(36 + 2 * samples);
  out << "WAVEfmt ";
  u32(16), u16(1), u16(1), u32(rate), u32(2 * rate), u16(2), u16(16);
  out << "data";
  u32(2 * samples);
  for (std::uint32_t k = 0; k < samples; ++k)
    u16(static_cast<std::uint16_t>(static_cast<std::int16_t>(8000 * std::sin(2 * M_PI * 220 * k / rate))));
}

class FaceCliTest : public testing::LipsyncCliTest {};

const std::string kInput = (kFixtures / "bump_map.lab").string();

TEST_F(FaceCliTest, MeshWritesAGlbAndNothingElse) {
  const RunResult result = run({"render", kInput, "--mesh", "face.glb", "--mesh-subdivision", "0"});
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_EQ(result.out, "");  // no track on stdout unless -o is given
  EXPECT_EQ(listing(), std::vector<std::string>{"face.glb"});
  const std::string bytes = read_text(dir_ / "face.glb");
  ASSERT_GT(bytes.size(), 20U);
  EXPECT_EQ(bytes.substr(0, 4), "glTF");
  std::uint32_t json_length = 0;
  std::memcpy(&json_length, bytes.data() + 12, 4);
  const auto json = nlohmann::json::parse(bytes.substr(20, json_length));
  EXPECT_EQ(json["asset"]["version"], "2.0");
  EXPECT_GE(json["meshes"][0]["primitives"][0]["targets"].size(), 2U);
  EXPECT_EQ(json["animations"][0]["samplers"][0]["interpolation"], "LINEAR");
}

TEST_F(FaceCliTest, MeshWithATrackFileWritesBoth) {
  const RunResult result = run({"render", kInput, "--mesh", "face.glb", "--mesh-subdivision=0", "-o", "track.json"});
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_EQ(listing(), (std::vector<std::string>{"face.glb", "track.json"}));
}

TEST_F(FaceCliTest, NoBlinksTakesTheFirstBlinkOutOfTheGlb) {
  ASSERT_EQ(run({"render", kInput, "--mesh", "blinks.glb", "--mesh-subdivision=0"}).status, 0);
  const RunResult result = run({"render", kInput, "--mesh", "open.glb", "--mesh-subdivision=0", "--no-blinks"});
  ASSERT_EQ(result.status, 0) << result.err;
  // The input ends at 1.039 s, in the first blink of the default schedule (from 1 s): only the
  // face with blinks has its lids half shut on the last frame.
  EXPECT_NE(read_text(dir_ / "open.glb"), read_text(dir_ / "blinks.glb"));
}

TEST_F(FaceCliTest, MeshSolveFullIsTheDefaultAndFastWritesAnotherFace) {
  ASSERT_EQ(run({"render", kInput, "--mesh", "full.glb", "--mesh-subdivision=0", "--mesh-solve", "full"}).status, 0);
  ASSERT_EQ(run({"render", kInput, "--mesh", "default.glb", "--mesh-subdivision=0"}).status, 0);
  const RunResult result = run({"render", kInput, "--mesh", "fast.glb", "--mesh-subdivision=0", "--mesh-solve=fast"});
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_EQ(read_text(dir_ / "full.glb"), read_text(dir_ / "default.glb"));
  EXPECT_NE(read_text(dir_ / "fast.glb"), read_text(dir_ / "full.glb"));
}

TEST_F(FaceCliTest, BadOptionsLeaveNoFile) {
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"render", kInput, "--mesh", "face.glb", "--mesh-subdivision", "3"},
        std::vector<std::string>{"render", kInput, "--audio", "x.wav"},
        std::vector<std::string>{"render", kInput, "--no-blinks", "-o", "track.json"},
        std::vector<std::string>{"render", kInput, "--mesh-solve", "fast", "-o", "track.json"},
        std::vector<std::string>{"render", kInput, "--mesh", "face.glb", "--mesh-solve", "quick"},
        std::vector<std::string>{"render", kInput, "--mesh", "no/such/dir/face.glb"}}) {
    const RunResult result = run(args);
    EXPECT_NE(result.status, 0);
    EXPECT_NE(result.err, "");
    EXPECT_TRUE(listing().empty()) << args.back();
  }
}

TEST_F(FaceCliTest, MissingFfmpegIsAClearErrorAndLeavesNoFile) {
  const RunResult result = run({"render", kInput, "--video", "face.mp4"},
                               {.stdin_file = std::nullopt, .path_env = (capture_ / "empty-path").string()});
  EXPECT_NE(result.status, 0);
  EXPECT_THAT(result.err, HasSubstr("ffmpeg was not found"));
  EXPECT_TRUE(listing().empty());
}

// ffprobe's view of a video: its video and audio streams (each as JSON).
struct ProbedVideo {
  nlohmann::json video, audio;
};

ProbedVideo probe_video(const fs::path& file, const fs::path& capture) {
  const RunResult probe = run_program({*find_program("ffprobe"), "-v", "error", "-count_frames", "-show_streams",
                                       "-show_format", "-of", "json", file.string()},
                                      file.parent_path(), capture);
  EXPECT_EQ(probe.status, 0) << probe.err;
  const auto info = nlohmann::json::parse(probe.out);
  EXPECT_EQ(info["streams"].size(), 2U);
  const bool video_first = info["streams"][0]["codec_type"] == "video";
  return {info["streams"][video_first ? 0 : 1], info["streams"][video_first ? 1 : 0]};
}

// Audio longer than the phonemes: the track and the video are extended to cover it, and
// the video ends within one frame after the audio.
TEST_F(FaceCliTest, VideoWithLongerAudioCoversTheAudio) {
  if (!find_program("ffmpeg") || !find_program("ffprobe")) GTEST_SKIP() << "ffmpeg/ffprobe not installed";
  write_wav(dir_ / "speech.wav", 1.2);
  const RunResult result =
      run({"render", kInput, "--video", "face.mp4", "--audio", "speech.wav", "--mesh-subdivision", "0"});
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_EQ(listing(), (std::vector<std::string>{"face.mp4", "speech.wav"}));
  const ProbedVideo probed = probe_video(dir_ / "face.mp4", capture_);
  EXPECT_EQ(probed.video["codec_name"], "h264");
  EXPECT_EQ(probed.audio["codec_type"], "audio");
  EXPECT_EQ(probed.video["r_frame_rate"], "30/1");
  EXPECT_EQ(std::stoi(probed.video["nb_read_frames"].get<std::string>()), 36);  // ⌈1.2 s · 30⌉
  EXPECT_NEAR(std::stod(probed.video["duration"].get<std::string>()),
              std::stod(probed.audio["duration"].get<std::string>()), 1.0 / 30);
  // The track's last frame is at or after the end of the audio.
  const RunResult track = run({"render", kInput, "--audio", "speech.wav", "--video", "again.mp4", "-o", "track.csv",
                               "--format", "csv", "--mesh-subdivision", "0"});
  ASSERT_EQ(track.status, 0) << track.err;
  const std::string csv = read_text(dir_ / "track.csv");
  const std::string last_line = csv.substr(csv.rfind('\n', csv.size() - 2) + 1);
  EXPECT_GE(std::stod(last_line.substr(0, last_line.find(','))), 1.2);
}

// Audio shorter than the phonemes: the video has the track's frames, as without audio.
TEST_F(FaceCliTest, VideoWithShorterAudioHasTheTrackDurationAndFrameCount) {
  if (!find_program("ffmpeg") || !find_program("ffprobe")) GTEST_SKIP() << "ffmpeg/ffprobe not installed";
  write_wav(dir_ / "speech.wav", 0.5);
  const RunResult result =
      run({"render", kInput, "--video", "face.mp4", "--audio", "speech.wav", "--mesh-subdivision", "0"});
  ASSERT_EQ(result.status, 0) << result.err;
  const ProbedVideo probed = probe_video(dir_ / "face.mp4", capture_);
  // The track of bump_map.lab ends at its last label's end; frames 0 .. ceil(end · 30).
  const RunResult track = run({"render", kInput, "--format", "csv"});
  ASSERT_EQ(track.status, 0);
  const std::string last_line = track.out.substr(track.out.rfind('\n', track.out.size() - 2) + 1);
  const double end_s = std::stod(last_line.substr(0, last_line.find(',')));
  const int frames = static_cast<int>(std::ceil(end_s * 30 - 1e-6)) + 1;
  EXPECT_EQ(std::stoi(probed.video["nb_read_frames"].get<std::string>()), frames) << "end " << end_s << " s";
  EXPECT_NEAR(std::stod(probed.video["duration"].get<std::string>()), frames / 30.0, 0.05);
}

TEST_F(FaceCliTest, StillWritesOnePng) {
  if (!find_program("ffmpeg")) GTEST_SKIP() << "ffmpeg not installed";
  const RunResult result =
      run({"render", kInput, "--still", "face.png", "--still-at", "0.3", "--mesh-subdivision", "0"});
  ASSERT_EQ(result.status, 0) << result.err;
  EXPECT_EQ(listing(), std::vector<std::string>{"face.png"});
  EXPECT_EQ(read_text(dir_ / "face.png").substr(1, 3), "PNG");
}

}  // namespace
}  // namespace lipsync
