// `lipsync render INPUT`: a timed phoneme file in, an animation track out.
//
// Every option is checked before any work is done, and the whole track is
// computed before the output file is created, so a bad command line or a bad
// input never leaves a file behind.
//
// With --mesh, --video or --still the track also drives the physics face
// (docs/face.md), simulated on the uniform --fps grid: --mesh writes a glTF
// binary (all or nothing, like -o); --video and --still rasterise the face in
// software and pipe raw RGB frames to ffmpeg (found on PATH), which writes a
// temporary file next to the destination that is renamed over it only when
// ffmpeg succeeded.
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>

#ifdef LIPSYNC_WITH_FACE
#include "lipsync/face/face_animation.hpp"
#include "lipsync/face/face_raster.hpp"
#endif

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "files.hpp"
#include "pipeline.hpp"

namespace lipsync::cli {
namespace {

static_assert(RenderOptions{}.fps == 30 && RenderOptions{}.lookahead == 7,
              "update the defaults shown by --help");
static_assert(SegmentOptions{}.closure_fraction == 0.6, "update the default shown by --help");

constexpr OptionSpec kOptions[] = {
    kTrackOutputOption,
    kTrackFormatOption,
    kFpsOption,
    {"model", 0, "FILE", "articulation model JSON (see 'lipsync model dump')", "the built-in model"},
    kPhoneSetOption,
    kInputFormatOption,
    kTierOption,
    kSampleRateOption,
    {"closure-fraction", 0, "F",
     "share of a /p b/ given to its closure when the input has no closure label, in (0, 1)", "0.6"},
    {"fixed-rate", 0, "", "uniform grid only: no key frames at closures and short phonemes", "off"},
    {"incremental", 0, "",
     "feed the phonemes one at a time through the streaming renderer (output identical to offline)", "off"},
    {"lookahead", 0, "N",
     "segments after a frame's own that must be known before it is computed, 0 to 7 (7 is exact)", "7"},
    {"mesh", 0, "FILE",
     "also simulate the physics face and write it as a glTF binary (.glb: mesh and morph-target animation)",
     "no mesh"},
    {"mesh-subdivision", 0, "N", "face mesh subdivision level for --mesh, --video and --still, 0 to 2", "1"},
    {"video", 0, "FILE", "also render a software preview of the face to FILE (.mp4, H.264; needs ffmpeg)",
     "no video"},
    {"audio", 0, "WAV", "audio muxed into --video (AAC)", "none"},
    {"still", 0, "FILE", "also render one preview frame of the face to FILE (.png; needs ffmpeg)", "no still"},
    {"still-at", 0, "SECONDS", "time of the --still frame, >= 0 (the nearest --fps frame)", "0"},
};

// ffmpeg as a child process: raw RGB24 frames on its stdin, its output a temporary file that
// becomes `destination` only on success.
std::string find_on_path(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::string_view rest = path ? path : "/usr/bin:/bin";
  while (true) {
    const auto colon = rest.find(':');
    const std::string dir(rest.substr(0, colon));
    const std::string candidate = (dir.empty() ? std::string(".") : dir) + "/" + program;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
    if (colon == std::string_view::npos) return {};
    rest.remove_prefix(colon + 1);
  }
}

class FfmpegWriter {
 public:
  // `output_args`: ffmpeg arguments after the raw-video input (and any extra inputs), without the
  // output file name, which is a temporary file next to `destination`.
  FfmpegWriter(const std::string& ffmpeg, const std::string& destination, int width, int height, int fps,
               const std::vector<std::string>& extra_inputs, const std::vector<std::string>& output_args)
      : destination_(destination) {
    const std::filesystem::path target(destination);
    temp_path_ = (target.parent_path() / ("." + target.filename().string() + ".tmp-" + std::to_string(::getpid())))
                     .string();
    std::vector<std::string> args = {ffmpeg, "-hide_banner", "-loglevel", "error", "-y",
                                     "-f", "rawvideo", "-pix_fmt", "rgb24", "-s",
                                     std::to_string(width) + "x" + std::to_string(height), "-r", std::to_string(fps),
                                     "-i", "pipe:0"};
    args.insert(args.end(), extra_inputs.begin(), extra_inputs.end());
    args.insert(args.end(), output_args.begin(), output_args.end());
    args.push_back(temp_path_);
    int fds[2];
    if (::pipe(fds) != 0) throw FileError(destination + ": cannot create a pipe to ffmpeg: " + std::strerror(errno));
    pid_ = ::fork();
    if (pid_ < 0) {
      ::close(fds[0]);
      ::close(fds[1]);
      throw FileError(destination + ": cannot start ffmpeg: " + std::strerror(errno));
    }
    if (pid_ == 0) {
      ::dup2(fds[0], STDIN_FILENO);
      ::close(fds[0]);
      ::close(fds[1]);
      const int null_out = ::open("/dev/null", O_WRONLY);
      if (null_out >= 0) ::dup2(null_out, STDOUT_FILENO);
      std::vector<char*> argv;
      for (std::string& arg : args) argv.push_back(arg.data());
      argv.push_back(nullptr);
      ::execv(args[0].c_str(), argv.data());
      ::_exit(127);
    }
    ::close(fds[0]);
    pipe_ = fds[1];
    ::signal(SIGPIPE, SIG_IGN);  // a dead ffmpeg shows as EPIPE, not as our death
  }
  ~FfmpegWriter() {
    if (pipe_ >= 0) ::close(pipe_);
    if (pid_ > 0 && !done_) {
      int status = 0;
      ::waitpid(pid_, &status, 0);
    }
    if (!committed_) ::unlink(temp_path_.c_str());
  }
  FfmpegWriter(const FfmpegWriter&) = delete;
  FfmpegWriter& operator=(const FfmpegWriter&) = delete;

  void write(const std::vector<std::uint8_t>& bytes) {
    std::size_t written = 0;
    while (written < bytes.size()) {
      const ssize_t n = ::write(pipe_, bytes.data() + written, bytes.size() - written);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) finish_failed("ffmpeg stopped reading its input");
      written += static_cast<std::size_t>(n);
    }
  }
  void commit() {
    ::close(pipe_);
    pipe_ = -1;
    int status = 0;
    ::waitpid(pid_, &status, 0);
    done_ = true;
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
      throw FileError(destination_ + ": ffmpeg failed (exit status " +
                      std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status)) +
                      "; its messages are above)");
    if (std::rename(temp_path_.c_str(), destination_.c_str()) != 0)
      throw FileError(destination_ + ": cannot rename the temporary file: " + std::strerror(errno));
    committed_ = true;
  }

 private:
  [[noreturn]] void finish_failed(const std::string& why) {
    ::close(pipe_);
    pipe_ = -1;
    int status = 0;
    ::waitpid(pid_, &status, 0);
    done_ = true;
    throw FileError(destination_ + ": " + why + " (its messages are above)");
  }

  std::string destination_, temp_path_;
  pid_t pid_ = -1;
  int pipe_ = -1;
  bool done_ = false, committed_ = false;
};

void check_output_directory(const std::string& option, const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  std::error_code error;
  if (!parent.empty() && !std::filesystem::is_directory(parent, error))
    throw FileError(path + ": --" + option + ": the directory '" + parent.string() + "' does not exist");
}

constexpr std::string_view kUsage = "lipsync render INPUT [options]";
constexpr std::string_view kDescription =
    "Renders a timed phoneme file (INPUT, or - for standard input) to a coarticulated\n"
    "animation track: one frame per grid step at --fps, plus key frames at the closure\n"
    "and release of /p b m f v/ and in phonemes too short for the grid.\n"
    "With --mesh, --video or --still it also simulates the physics face on the\n"
    "uniform grid (docs/face.md); the track is then written only if -o is given.";

}  // namespace

int run_render(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "render");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (arguments.positional().empty()) {
    throw UsageError("render needs an INPUT file (or - for standard input) (see 'lipsync render --help')");
  }
  if (arguments.positional().size() > 1) {
    throw UsageError("render takes one INPUT, got also '" + arguments.positional()[1] + "'");
  }
  const std::string& input = arguments.positional().front();

  const std::string output = arguments.value("output").value_or("-");
  const TrackFormat format = parse_track_format_option(arguments.value("format").value_or("json"));
  std::optional<InputFormat> input_format;
  if (const auto text = arguments.value("input-format")) input_format = parse_input_format_option(*text);

  ParseOptions parse_options;
  if (const auto tier = arguments.value("tier")) {
    if (tier->empty()) throw UsageError("--tier: the tier name must not be empty");
    parse_options.tier = *tier;
  }
  if (const auto rate = arguments.value("sample-rate")) {
    parse_options.timit_sample_rate_hz = parse_int_option("sample-rate", *rate, 1, 100'000'000);
  }

  const RenderPlan plan = parse_render_plan(arguments);
  TrackRequest request;
  request.render = plan.render;
  request.segments = plan.segments;
  request.incremental = arguments.flag("incremental");
  const std::optional<std::string> phone_set_name = arguments.value("phone-set");
  if (phone_set_name && phone_set_name->empty()) throw UsageError("--phone-set: the name must not be empty");

  if (input == "-" && arguments.value("model") == "-") {
    throw UsageError("--model: '-' and INPUT '-' cannot both read standard input");
  }
  const std::optional<std::string> mesh_path = arguments.value("mesh");
  const std::optional<std::string> video_path = arguments.value("video");
  const std::optional<std::string> audio_path = arguments.value("audio");
  const std::optional<std::string> still_path = arguments.value("still");
  [[maybe_unused]] const int subdivision = plan.mesh_subdivision;  // only with LIPSYNC_WITH_FACE
  double still_at_s = 0.0;
  if (const auto text = arguments.value("still-at")) {
    still_at_s = parse_double_option("still-at", *text);
    if (!(still_at_s >= 0.0 && std::isfinite(still_at_s))) throw UsageError("--still-at: '" + *text + "' must be >= 0");
    if (!still_path) throw UsageError("--still-at needs --still FILE");
  }
  if (audio_path && !video_path) throw UsageError("--audio needs --video FILE");
  const bool face_outputs = mesh_path || video_path || still_path;
#ifndef LIPSYNC_WITH_FACE
  if (face_outputs) {
    throw UsageError(std::string(mesh_path ? "--mesh" : video_path ? "--video" : "--still") +
                     ": this lipsync was built without the physics face (LIPSYNC_BUILD_FACE=OFF)");
  }
#endif
  if (!face_outputs && arguments.value("mesh-subdivision"))
    throw UsageError("--mesh-subdivision needs --mesh, --video or --still");
  const std::pair<const char*, std::optional<std::string>> face_files[] = {
      {"mesh", mesh_path}, {"video", video_path}, {"still", still_path}};
  for (const auto& [option, path] : face_files) {
    if (path && (path->empty() || *path == "-")) throw UsageError(std::string("--") + option + ": needs a file name");
    if (path) check_output_directory(option, *path);
  }
  std::string ffmpeg;
  if (video_path || still_path) {
    ffmpeg = find_on_path("ffmpeg");
    if (ffmpeg.empty())
      throw FileError(std::string(video_path ? "--video" : "--still") +
                      ": ffmpeg was not found on PATH (install it, e.g. 'apt-get install ffmpeg')");
  }
  if (audio_path && ::access(audio_path->c_str(), R_OK) != 0)
    throw FileError(*audio_path + ": --audio: cannot read the file: " + std::strerror(errno));

  const ModelSource model_source(arguments.value("model"));
  const ArticulationModel& model = model_source.model();

  const std::string content = read_file(input);
  const std::string source = input == "-" ? std::string(kStdinName) : input;
  const InputFormat chosen_format = input_format ? *input_format : detect_input_format(source, content);
  const LabeledUtterance utterance = parse_utterance(content, chosen_format, source, parse_options);

  std::vector<PhoneSet> candidates;
  const PhoneSet& phone_set = choose_phone_set(phone_set_name, utterance, model, candidates);
  const Track track = render_utterance(utterance, model, phone_set, request);
  if (!face_outputs) {
    write_output(track, model, format, output);
    return 0;
  }
  if (arguments.value("output")) write_output(track, model, format, output);
#ifdef LIPSYNC_WITH_FACE
  // The face: simulated once on the uniform grid, then exported and/or rendered.
  const face::FaceMesh mesh = face::build_face_mesh(face::FaceAsset::builtin(), subdivision);
  const face::FaceRig rig = arguments.value("model")
                                ? face::FaceRig::from_json(face::FaceRig::builtin_json(), "rig.json", model)
                                : face::FaceRig::builtin();
  // The face is driven by the uniform grid only (as with --fixed-rate), rendered at the solver's
  // step rate (one step per frame from 30 fps up, ⌈30 / fps⌉ below) so that every step sees the
  // engine's own values; poses are kept at --fps.
  TrackRequest face_request = request;
  face_request.render.fixed_rate = true;
  face_request.render.fps = request.render.fps * ((30 + request.render.fps - 1) / request.render.fps);
  const Track face_track = render_utterance(utterance, model, phone_set, face_request);
  const face::FaceAnimation animation = face::simulate_face_animation(mesh, rig, face_track, request.render.fps);
  if (mesh_path) {
    AtomicOutputFile file(*mesh_path);
    face::write_face_glb(file.stream(), mesh, animation);
    file.commit();
  }
  face::RasterOptions raster;
  std::vector<std::uint8_t> rgb;
  if (video_path) {
    std::vector<std::string> extra_inputs, output_args = {"-map", "0:v"};
    if (audio_path) {
      extra_inputs = {"-i", *audio_path};
      output_args.insert(output_args.end(), {"-map", "1:a", "-c:a", "aac", "-b:a", "128k"});
    }
    output_args.insert(output_args.end(), {"-c:v", "libx264", "-preset", "veryfast", "-crf", "20", "-pix_fmt",
                                           "yuv420p", "-movflags", "+faststart", "-f", "mp4"});
    FfmpegWriter writer(ffmpeg, *video_path, raster.width, raster.height, request.render.fps, extra_inputs,
                        output_args);
    for (std::size_t k = 0; k < animation.frame_count(); ++k) {
      face::render_face_rgb(mesh, animation.frame(k), raster, rgb);
      writer.write(rgb);
    }
    writer.commit();
  }
  if (still_path) {
    const auto frame = static_cast<std::size_t>(std::llround(still_at_s * request.render.fps));
    face::render_face_rgb(mesh, animation.frame(std::min(frame, animation.frame_count() - 1)), raster, rgb);
    FfmpegWriter writer(ffmpeg, *still_path, raster.width, raster.height, request.render.fps, {},
                        {"-frames:v", "1", "-c:v", "png", "-f", "image2", "-update", "1"});
    writer.write(rgb);
    writer.commit();
  }
#endif
  return 0;
}

}  // namespace lipsync::cli
