// The render pipeline shared by `lipsync render` and `lipsync demo`:
//
//   bytes → format (detected or named) → LabeledUtterance → phone set
//         → segments → track → writer → stdout or an atomic output file
//
// The incremental path feeds the same intervals one at a time through
// SegmentBuilder::push and StreamingRenderer::push; its output is the same
// track, byte for byte, which is what the CLI tests check from the outside.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "arguments.hpp"
#include "format_choices.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/model.hpp"
#include "lipsync/moho_writer.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/render_plan.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/track.hpp"
#include "lipsync/track_writer.hpp"
#include "lipsync/utterance.hpp"
#include "lipsync/viseme_writer.hpp"
#include "lipsync/visemes.hpp"
#include "setting_help.hpp"

namespace lipsync::cli {

// Options shared by the commands that read phoneme files or write tracks.
inline constexpr OptionSpec kTrackOutputOption = {
    "output", 'o', "FILE", "write the track to FILE (all or nothing, via a temporary file); - for stdout", "stdout"};
inline constexpr OptionSpec kTrackFormatOption = {
    "format", 0, "FORMAT", kJoinedText<"track format: ", kNameList<kTrackFormats, ListStyle::choice_noted>>.view(),
    "json"};
inline constexpr OptionSpec kRenderFormatOption = {
    "format", 0, "FORMAT",
    kJoinedText<"track format: ", kNameList<kTrackFormats, ListStyle::commas_noted>, ", or visemes: ",
                kNameList<kVisemeFormats, ListStyle::commas_noted>, ", or ",
                kNameList<kMouthSwitchFormats, ListStyle::commas_noted>>.view(),
    "json"};
inline constexpr OptionSpec kMohoFpsOption = {
    "moho-fps", 0, "N",
    "frames per second of --format moho-dat's frame numbers (the Moho project's frame rate), 1 to 1000", "24"};
inline constexpr OptionSpec kExtendedShapesOption = {
    "extended-shapes", 0, "LETTERS",
    "which of Rhubarb's optional mouth shapes G, H and X the rhubarb formats use (its extendedShapes option); "
    "\"\" for none",
    "GHX"};
inline constexpr OptionSpec kFpsOption = {"fps", 0, "N",
                                          kRangedHelp<"frames per second of the uniform grid", kFpsSetting>.view(),
                                          kDefaultText<kFpsSetting>.view()};
/// --fps of the commands that write the rhubarb formats, which default to Rhubarb's 10 ms cues.
inline constexpr OptionSpec kFpsOrRhubarbCuesOption = {
    "fps", 0, "N", kFpsOption.help,
    kJoinedText<kDefaultText<kFpsSetting>, "; ", kDefaultText<IntSetting{1, 240, kRhubarbCueFps}>,
                " for the rhubarb formats, Rhubarb's 10 ms cues">.view()};
inline constexpr OptionSpec kPhoneSetOption = {
    "phone-set", 0, "NAME", "phone set of the labels (see 'lipsync phone-sets'), or auto to detect it",
    "the set the file declares, else auto"};
inline constexpr OptionSpec kInputFormatOption = {"input-format", 0, "FORMAT",
                                                  kNameList<kInputFormats, ListStyle::choice>.view(),
                                                  "detected from the content, then the file extension"};
inline constexpr OptionSpec kTierOption = {"tier", 0, "NAME", "TextGrid tier that holds the phonemes", "phones"};
inline constexpr OptionSpec kSampleRateOption = {
    "sample-rate", 0, "HZ", "sample rate of the sample numbers in a TIMIT .PHN file, > 0", "16000"};

/// The built-in model, or `path` read and validated (errors name the file).
class ModelSource {
 public:
  explicit ModelSource(const std::optional<std::string>& path);
  const ArticulationModel& model() const { return loaded_ ? *loaded_ : ArticulationModel::builtin(); }
  /// The model's JSON text as read (the embedded text for the built-in model).
  const std::string& json_text() const { return json_text_; }

 private:
  std::optional<ArticulationModel> loaded_;
  std::string json_text_;
};

/// The reader options --tier and --sample-rate (UsageError for a bad value).
ParseOptions parse_options_from(const Arguments& arguments);

/// --format and --input-format values; UsageError listing the choices otherwise.
TrackFormat parse_track_format_option(std::string_view text);

/// `lipsync render`'s --format: a track format or a viseme format (exactly one is set).
struct RenderFormat {
  std::optional<TrackFormat> track;
  std::optional<VisemeFormat> visemes;
  bool moho_switch = false;  ///< moho-dat (lipsync/moho_writer.hpp): neither of the above
};
RenderFormat parse_render_format_option(std::string_view text);
InputFormat parse_input_format_option(std::string_view text);
/// --mesh-solve (render, say, stream, loadtest): true for "fast", false for "full" (docs/face.md,
/// "Solves"); UsageError otherwise.
bool parse_fast_mesh_solve_option(std::string_view text);

/// Names of the built-in phone sets plus "auto", for messages.
std::string phone_set_choices();

/// The phone set for `utterance`: `requested` if given ("auto" detects), else
/// the set the file declares, else detection over all built-in sets. Throws
/// UsageError for an unknown requested name, InputError for an unknown
/// declared name. The result points into `candidates`.
const PhoneSet& choose_phone_set(const std::optional<std::string>& requested, const LabeledUtterance& utterance,
                                 const ArticulationModel& model, std::vector<PhoneSet>& candidates);

/// The render settings a command was given (--fps, --lookahead, --fixed-rate,
/// --closure-fraction, --mesh-subdivision: those in its table; the others keep
/// their defaults, the frame rate `fps_when_not_given` if set), resolved and range-checked by the
/// core's render plan. UsageError naming the option and the value otherwise.
RenderPlan parse_render_plan(const Arguments& arguments, std::optional<std::int64_t> fps_when_not_given = std::nullopt);

struct TrackRequest {
  SegmentOptions segments;
  RenderOptions render;
  bool incremental = false;  ///< stream the intervals one at a time
};

/// Segments and renders `utterance`. Throws InputError for bad timing or labels.
Track render_utterance(const LabeledUtterance& utterance, const ArticulationModel& model, const PhoneSet& phone_set,
                       const TrackRequest& request);

/// Writes `track` to `output` ("-" for standard output) atomically. Throws FileError.
void write_output(const Track& track, const ArticulationModel& model, TrackFormat format, const std::string& output);

/// Writes the visemes of `track` (an utterance ending at `end_us`) in `format` to `output`
/// atomically. Throws FileError.
void write_viseme_output(const Track& track, const ArticulationModel& model, const VisemeOptions& options,
                         VisemeFormat format, std::int64_t end_us, const std::string& output);

/// Writes the Moho switch data of `track` (Rhubarb visemes with `options`' shapes) at `fps` frames
/// per second to `output` atomically. Throws FileError.
void write_moho_output(const Track& track, const ArticulationModel& model, const VisemeOptions& options, int fps,
                       std::int64_t end_us, const std::string& output);

}  // namespace lipsync::cli
