// Writers for rendered tracks, in the formats engines already read
// (docs/output-formats.md). They write to a stream; files are the caller's.
//
//   json       {"format","fps","channels","arkit_names","frames":[{t,t_us,kind,values,arkit}]}
//   csv        t,t_us,kind,<channel>...  one row per frame
//   arkit-csv  Unreal Live Link Face CSV (61 columns, PascalCase names, Timecode)
#pragma once

#include <optional>
#include <ostream>
#include <string_view>

#include "lipsync/model.hpp"
#include "lipsync/track.hpp"

namespace lipsync {

enum class TrackFormat { json, csv, arkit_csv };

std::string_view to_string(TrackFormat format);
std::optional<TrackFormat> track_format_from_string(std::string_view name);

void write_track(const Track& track, const ArticulationModel& model, TrackFormat format,
                 std::ostream& out);

}  // namespace lipsync
