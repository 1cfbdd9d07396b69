// Writers for rendered tracks, in the formats engines already read
// (docs/output-formats.md). They write to a stream; files are the caller's.
//
//   json       {"format","fps","channels","arkit_names","frames":[{t,t_us,kind,values,arkit}]}
//   csv        t,t_us,kind,<channel>...  one row per frame
//   arkit-csv  Unreal Live Link Face CSV (61 columns, PascalCase names, Timecode)
//
// There is one writer, over a NamedTrackView: the track with its model name,
// channel names, ARKit names and ARKit weights given as data. `lipsync render`
// fills it from a local ArticulationModel (the model-based write_track); the
// network commands fill it from a stream whose model only the server has.
#pragma once

#include <optional>
#include <ostream>
#include <span>
#include <string_view>

#include "lipsync/model.hpp"
#include "lipsync/named_format.hpp"
#include "lipsync/track.hpp"

namespace lipsync {

enum class TrackFormat { json, csv, arkit_csv };

/// The track formats by name, in the order help lists them.
inline constexpr std::array<NamedFormat<TrackFormat>, 3> kTrackFormats{{
    {TrackFormat::json, "json"},
    {TrackFormat::csv, "csv"},
    {TrackFormat::arkit_csv, "arkit-csv", "Unreal Live Link Face CSV"},
}};

std::string_view to_string(TrackFormat format);
std::optional<TrackFormat> track_format_from_string(std::string_view name);

/// A track with the names that go with its values. It only refers to them: the
/// caller keeps the names and arrays alive while writing.
struct NamedTrackView {
  std::string_view model;                           ///< name of the model that produced the track
  std::span<const std::string_view> channel_names;  ///< one per track channel, in value order
  /// Names of the ARKit weights in `arkit` order (Apple camelCase, as kArkitNames);
  /// empty when there are none. Live Link Face columns are bound to them by name;
  /// a column whose shape is not among them is written as 0.
  std::span<const std::string_view> arkit_names = {};
  const Track& track;
  std::span<const float> arkit = {};  ///< frame-major, track.frame_count() × arkit_names.size()
};

/// Writes `view` in `format`. The csv ignores the ARKit weights; arkit-csv needs
/// them and a track rate of at least 1 fps. Throws std::invalid_argument when
/// the names and arrays disagree in size.
void write_track(const NamedTrackView& view, TrackFormat format, std::ostream& out);

/// Writes `track`, a track of `model`, in `format`: its names are the model's and
/// its ARKit weights (json, arkit-csv) the model's retargeting of every frame.
/// Throws std::invalid_argument when the track does not have the model's channels.
void write_track(const Track& track, const ArticulationModel& model, TrackFormat format, std::ostream& out);

}  // namespace lipsync
