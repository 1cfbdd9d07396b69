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
#include "lipsync/speech/audio.hpp"
#include "pipeline.hpp"
#include "render_outputs.hpp"
#include "speech_input.hpp"

namespace lipsync::cli {
namespace {

constexpr OptionSpec kOptions[] = {
    kTrackOutputOption,
    kRenderFormatOption,
    kExtendedShapesOption,
    kMohoFpsOption,
    kFpsOrRhubarbCuesOption,
    kModelOption,
    kPhoneSetOption,
    kInputFormatOption,
    kTierOption,
    kSampleRateOption,
    kClosureFractionOption,
    kFixedRateOption,
    kIncrementalOption,
    kLookaheadOption,
    kMeshOption,
    kMeshSubdivisionOption,
    kVideoOption,
    {"audio", 0, "WAV", "audio muxed into --video (AAC); a WAV's length extends the track to cover it",
     "a WAV INPUT, else none"},
    kStillOption,
    kStillAtOption,
    kNoBlinksOption,
    kMeshSolveOption,
    kTextOption,
    kTextFileOption,
    kRecordingVoiceOption,
    kAlignerOption,
};

// ffmpeg as a child process: raw RGB24 frames on its stdin, its output a temporary file that
// becomes `destination` only on success.
std::string find_on_path(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::string_view rest = path ? path : "/usr/bin:/bin";
  while (true) {
    const auto colon = rest.find(':');
    const std::string dir(rest.substr(0, colon));
    std::string candidate = (dir.empty() ? std::string(".") : dir) + "/" + program;
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
    temp_path_ =
        (target.parent_path() / ("." + target.filename().string() + ".tmp-" + std::to_string(::getpid()))).string();
    std::vector<std::string> args = {ffmpeg,
                                     "-hide_banner",
                                     "-loglevel",
                                     "error",
                                     "-y",
                                     "-f",
                                     "rawvideo",
                                     "-pix_fmt",
                                     "rgb24",
                                     "-s",
                                     std::to_string(width) + "x" + std::to_string(height),
                                     "-r",
                                     std::to_string(fps),
                                     "-i",
                                     "pipe:0"};
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
      argv.reserve(args.size() + 1);
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
    "A WAV INPUT is recorded speech: it is aligned to --text / --text-file with\n"
    "PocketSphinx (without them, to the words it recognises, or its phones: less exact), or, with a\n"
    "non-English --voice, against espeak-ng's rendering of the transcript; it is the\n"
    "sound of --video. With audio the track covers it to its end.\n"
    "With --mesh, --video or --still it also simulates the physics face on the\n"
    "uniform grid (docs/face.md); the track is then written only if -o is given.";

}  // namespace

OutputRequest parse_output_request(const Arguments& arguments) {
  OutputRequest out;
  out.output = arguments.value("output").value_or("-");
  out.output_given = arguments.value("output").has_value();
  out.format = parse_render_format_option(arguments.value("format").value_or("json"));
  if (out.format.visemes) out.visemes.vocabulary = vocabulary_of(*out.format.visemes);
  if (out.format.moho_switch) out.visemes.vocabulary = VisemeVocabulary::rhubarb;
  if (const auto text = arguments.value("moho-fps")) {
    if (!out.format.moho_switch) {
      throw UsageError("--moho-fps needs --format " +
                       std::string(name_of(kMouthSwitchFormats, MouthSwitchFormat::moho_dat)));
    }
    out.moho_fps = parse_int_option("moho-fps", *text, kMinMohoFps, kMaxMohoFps);
  }
  if (const auto letters = arguments.value("extended-shapes")) {
    if (out.visemes.vocabulary != VisemeVocabulary::rhubarb || !out.format.visemes)
      throw UsageError("--extended-shapes needs --format " + std::string(to_string(VisemeFormat::rhubarb_tsv)) +
                       " or " + std::string(to_string(VisemeFormat::rhubarb_json)));
    const auto shapes = rhubarb_shapes_from_string(*letters);
    if (!shapes)
      throw UsageError("--extended-shapes: '" + *letters + "' is not a set of G, H and X (e.g. GHX, GX or \"\")");
    out.visemes.rhubarb_shapes = *shapes;
  }
  TrackRequest& request = out.track;
  // Rhubarb writes its cues on a 10 ms grid; its formats follow it unless --fps says otherwise.
  const bool rhubarb_cues = out.format.visemes && out.visemes.vocabulary == VisemeVocabulary::rhubarb;
  const RenderPlan plan =
      parse_render_plan(arguments, rhubarb_cues ? std::optional<std::int64_t>(kRhubarbCueFps) : std::nullopt);
  request.render = plan.render;
  request.segments = plan.segments;
  request.incremental = arguments.flag("incremental");
  out.phone_set_name = arguments.value("phone-set");
  if (out.phone_set_name && out.phone_set_name->empty()) throw UsageError("--phone-set: the name must not be empty");
  out.model_path = arguments.value("model");
  out.mesh_path = arguments.value("mesh");
  out.video_path = arguments.value("video");
  out.audio_path = arguments.value("audio");
  out.still_path = arguments.value("still");
  out.subdivision = plan.mesh_subdivision;
  out.blinks = !arguments.flag("no-blinks");
  if (const auto solve = arguments.value("mesh-solve")) out.fast_solve = parse_fast_mesh_solve_option(*solve);
  if (const auto text = arguments.value("still-at")) {
    out.still_at_s = parse_double_option("still-at", *text);
    if (!(out.still_at_s >= 0.0 && std::isfinite(out.still_at_s)))
      throw UsageError("--still-at: '" + *text + "' must be >= 0");
    if (!out.still_path) throw UsageError("--still-at needs --still FILE");
  }
  if (out.audio_path && !out.video_path) throw UsageError("--audio needs --video FILE");
  const bool face_outputs = out.mesh_path || out.video_path || out.still_path;
#ifndef LIPSYNC_WITH_FACE
  if (face_outputs) {
    throw UsageError(std::string(out.mesh_path    ? "--mesh"
                                 : out.video_path ? "--video"
                                                  : "--still") +
                     ": this lipsync was built without the physics face (LIPSYNC_BUILD_FACE=OFF)");
  }
#endif
  if (!face_outputs && arguments.value("mesh-subdivision"))
    throw UsageError("--mesh-subdivision needs --mesh, --video or --still");
  if (!face_outputs && !out.blinks) throw UsageError("--no-blinks needs --mesh, --video or --still");
  if (!face_outputs && arguments.value("mesh-solve")) throw UsageError("--mesh-solve needs --mesh, --video or --still");
  const std::pair<const char*, std::optional<std::string>> face_files[] = {
      {"mesh", out.mesh_path}, {"video", out.video_path}, {"still", out.still_path}};
  for (const auto& [option, path] : face_files) {
    if (path && (path->empty() || *path == "-")) throw UsageError(std::string("--") + option + ": needs a file name");
    if (path) check_output_directory(option, *path);
  }
  if (out.video_path || out.still_path) {
    out.ffmpeg = find_on_path("ffmpeg");
    if (out.ffmpeg.empty())
      throw FileError(std::string(out.video_path ? "--video" : "--still") +
                      ": ffmpeg was not found on PATH (install it, e.g. 'apt-get install ffmpeg')");
  }
  if (out.audio_path && ::access(out.audio_path->c_str(), R_OK) != 0)
    throw FileError(*out.audio_path + ": --audio: cannot read the file: " + std::strerror(errno));
  return out;
}

void render_outputs(const OutputRequest& out, LabeledUtterance utterance) {
  const TrackRequest& request = out.track;
  // Used only with the face (--video), which a client-only build leaves out.
  [[maybe_unused]] const std::int64_t phonemes_end_us =
      utterance.intervals.empty() ? 0 : utterance.intervals.back().end_us;
  if (out.audio_end_us) speech::cover_audio(utterance, *out.audio_end_us, request.render.fps);
  const ModelSource model_source(out.model_path);
  const ArticulationModel& model = model_source.model();
  std::vector<PhoneSet> candidates;
  const PhoneSet& phone_set = choose_phone_set(out.phone_set_name, utterance, model, candidates);
  const Track track = render_utterance(utterance, model, phone_set, request);
  const auto write = [&] {
    if (out.format.track) {
      write_output(track, model, *out.format.track, out.output);
    } else {
      // The visemes of the utterance, which ends where its last phoneme (or the audio) does.
      const std::int64_t end_us = utterance.intervals.empty() ? 0 : utterance.intervals.back().end_us;
      if (out.format.moho_switch) {
        write_moho_output(track, model, out.visemes, out.moho_fps, end_us, out.output);
      } else {
        write_viseme_output(track, model, out.visemes, *out.format.visemes, end_us, out.output);
      }
    }
  };
  const bool face_outputs = out.mesh_path || out.video_path || out.still_path;
  if (!face_outputs) {
    write();
    return;
  }
  if (out.output_given) write();
#ifdef LIPSYNC_WITH_FACE
  // The face: simulated once on the uniform grid, then exported and/or rendered.
  const face::FaceMesh mesh = face::build_face_mesh(face::FaceAsset::builtin(), out.subdivision);
  const face::FaceRig rig = out.model_path ? face::FaceRig::from_json(face::FaceRig::builtin_json(), "rig.json", model)
                                           : face::FaceRig::builtin();
  // One face per input: the track's own frames (key frames included) stepped as lipsyncd steps its
  // mesh output (face::FaceTrackStepper); the glb keeps those poses, the video and the still show
  // them on the --fps grid, linear between frames as a glTF player does.
  const face::FaceAnimation track_faces = face::simulate_track_frames(
      mesh, rig, track, out.fast_solve ? face::fast_face_solver_params() : face::FaceSolverParams{},
      {.enabled = out.blinks, .seed = 1});
  if (out.mesh_path) {
    AtomicOutputFile file(*out.mesh_path);
    // Keys within 0.01 mm of every track frame: the glb plays the streamed poses (docs/face.md).
    face::write_face_glb(file.stream(), mesh, track_faces, {.key_tolerance_m = 0.00001});
    file.commit();
  }
  const face::FaceAnimation animation = (out.video_path || out.still_path)
                                            ? face::resample_face_animation(track_faces, request.render.fps)
                                            : face::FaceAnimation{};
  face::RasterOptions raster;
  std::vector<std::uint8_t> rgb;
  if (out.video_path) {
    std::vector<std::string> extra_inputs, output_args = {"-map", "0:v"};
    if (out.audio_path) {
      extra_inputs = {"-i", *out.audio_path};
      output_args.insert(output_args.end(), {"-map", "1:a", "-c:a", "aac", "-b:a", "128k"});
    }
    output_args.insert(output_args.end(), {"-c:v", "libx264", "-preset", "veryfast", "-crf", "20", "-pix_fmt",
                                           "yuv420p", "-movflags", "+faststart", "-f", "mp4"});
    FfmpegWriter writer(out.ffmpeg, *out.video_path, raster.width, raster.height, request.render.fps, extra_inputs,
                        output_args);
    std::size_t frame_count = animation.frame_count();
    if (out.audio_end_us && *out.audio_end_us >= phonemes_end_us) {
      // The frames that start before the audio ends, not the one cover_audio added at or
      // after its end: the video then ends within a frame of its sound.
      const auto frames = static_cast<std::size_t>((*out.audio_end_us * request.render.fps + 999'999) / 1'000'000);
      frame_count = std::min(frame_count, std::max<std::size_t>(1, frames));
    }
    for (std::size_t k = 0; k < frame_count; ++k) {
      face::render_face_rgb(mesh, animation.frame(k), raster, rgb);
      writer.write(rgb);
    }
    writer.commit();
  }
  if (out.still_path) {
    const auto frame = static_cast<std::size_t>(std::llround(out.still_at_s * request.render.fps));
    face::render_face_rgb(mesh, animation.frame(std::min(frame, animation.frame_count() - 1)), raster, rgb);
    FfmpegWriter writer(out.ffmpeg, *out.still_path, raster.width, raster.height, request.render.fps, {},
                        {"-frames:v", "1", "-c:v", "png", "-f", "image2", "-update", "1"});
    writer.write(rgb);
    writer.commit();
  }
#endif
}

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
  std::optional<InputFormat> input_format;
  if (const auto text = arguments.value("input-format")) input_format = parse_input_format_option(*text);
  const ParseOptions parse_options = parse_options_from(arguments);
  if (input == "-" && arguments.value("model") == "-") {
    throw UsageError("--model: '-' and INPUT '-' cannot both read standard input");
  }
  const RecordingAlignment recording = recording_alignment_options(arguments);
  const std::optional<std::string>& transcript = recording.transcript;
  OutputRequest out = parse_output_request(arguments);

  const std::string content = read_file(input);
  const std::string source = input == "-" ? std::string(kStdinName) : input;
  LabeledUtterance utterance;
  if (speech::looks_like_wav(content)) {
    // Recorded speech: aligned (or its phones recognised), and it is the video's sound.
    if (input_format) throw UsageError("--input-format: INPUT '" + source + "' is a WAV file, not a phoneme file");
    const speech::Alignment alignment = align_wav(content, source, recording);
    utterance = alignment.phones;
    out.audio_end_us = speech::wav_layout_and_duration_us(content, source).second;
    if (out.video_path && !out.audio_path && input != "-") out.audio_path = input;
  } else {
    if (transcript) throw UsageError("--text and --text-file need a WAV INPUT, and '" + source + "' is not one");
    if (arguments.value("voice") || arguments.value("aligner"))
      throw UsageError("--voice and --aligner need a WAV INPUT, and '" + source + "' is not one");
    const InputFormat chosen_format = input_format ? *input_format : detect_input_format(source, content);
    utterance = parse_utterance(content, chosen_format, source, parse_options);
    if (out.audio_path) out.audio_end_us = wav_duration_if_wav(*out.audio_path);
  }
  render_outputs(out, utterance);
  return 0;
}

}  // namespace lipsync::cli
