// The output half of `lipsync render`, shared with `lipsync say`: the options
// that say what to write (track or visemes, glTF mesh, video, still) are checked once,
// before any work, and a LabeledUtterance is then rendered to all of them.
#pragma once

#include <optional>
#include <string>

#include "arguments.hpp"
#include "pipeline.hpp"

namespace lipsync::cli {

// The options of these outputs, shared by the commands that render.
inline constexpr OptionSpec kModelOption = {"model", 0, "FILE", "articulation model JSON (see 'lipsync model dump')",
                                            "the built-in model"};
// A fraction has no compile-time decimal form here: its default is written out and checked.
static_assert(kDefaultClosureFraction == 0.6, "update the default shown by --help for --closure-fraction");
inline constexpr OptionSpec kClosureFractionOption = {
    "closure-fraction", 0, "F", "share of a /p b/ given to its closure when the input has no closure label, in (0, 1)",
    "0.6"};
inline constexpr OptionSpec kFixedRateOption = {
    "fixed-rate", 0, "", "uniform grid only: no key frames at closures and short phonemes", "off"};
inline constexpr OptionSpec kIncrementalOption = {
    "incremental", 0, "",
    "feed the phonemes one at a time through the streaming renderer (output identical to offline)", "off"};
inline constexpr OptionSpec kLookaheadOption = {
    "lookahead", 0, "N",
    kRangedHelp<"segments after a frame's own that must be known before it is computed", kLookaheadSetting,
                " (the maximum is exact)">.view(),
    kDefaultText<kLookaheadSetting>.view()};
inline constexpr OptionSpec kMeshOption = {
    "mesh", 0, "FILE",
    "also simulate the physics face and write it as a glTF binary (.glb: mesh and morph-target animation)", "no mesh"};
inline constexpr OptionSpec kMeshSubdivisionOption = {
    "mesh-subdivision", 0, "N",
    kRangedHelp<"face mesh subdivision level for --mesh, --video and --still", kMeshSubdivisionSetting>.view(),
    kDefaultText<kMeshSubdivisionSetting>.view()};
inline constexpr OptionSpec kVideoOption = {
    "video", 0, "FILE", "also render a software preview of the face to FILE (.mp4, H.264; needs ffmpeg)", "no video"};
inline constexpr OptionSpec kStillOption = {
    "still", 0, "FILE", "also render one preview frame of the face to FILE (.png; needs ffmpeg)", "no still"};
inline constexpr OptionSpec kNoBlinksOption = {
    "no-blinks", 0, "", "the face's eyes stay open (no blinks) in --mesh, --video and --still", "blinks"};
inline constexpr OptionSpec kMeshSolveOption = {
    "mesh-solve", 0, "full|fast",
    "the face's solve for --mesh, --video and --still: fast takes about 0.45 of full's CPU, closures sealed, "
    "poses within 0.1 mm on average (docs/face.md, \"Solves\")",
    "full"};
inline constexpr OptionSpec kStillAtOption = {"still-at", 0, "SECONDS",
                                              "time of the --still frame, >= 0 (the nearest --fps frame)", "0"};

struct OutputRequest {
  std::string output = "-";  ///< -o, "-" for stdout
  bool output_given = false;
  RenderFormat format{TrackFormat::json, std::nullopt};  ///< --format: a track or a viseme format
  VisemeOptions visemes;                                 ///< with a viseme format: vocabulary, Rhubarb shapes
  int moho_fps = 24;                                     ///< --moho-fps, with --format moho-dat
  TrackRequest track;
  std::optional<std::string> phone_set_name, model_path;
  std::optional<std::string> mesh_path, video_path, audio_path, still_path;
  int subdivision = 1;
  bool blinks = true;       ///< --no-blinks turns them off
  bool fast_solve = false;  ///< --mesh-solve fast
  double still_at_s = 0.0;
  std::string ffmpeg;  ///< found on PATH when --video or --still is given
  /// Length of the speech the track goes with, when known: the track is extended to
  /// cover it (its last frame at or after the end) and the video ends with it (its
  /// last frame is the one shown when the audio ends).
  std::optional<std::int64_t> audio_end_us;
};

/// Reads and checks the output options present in `arguments` (absent ones keep
/// their defaults). Throws UsageError or FileError.
OutputRequest parse_output_request(const Arguments& arguments);

/// Renders `utterance` to every output `request` names. Throws InputError or FileError.
void render_outputs(const OutputRequest& request, LabeledUtterance utterance);

}  // namespace lipsync::cli
