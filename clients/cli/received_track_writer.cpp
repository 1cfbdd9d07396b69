// Received tracks written with the server's names (see received_track_writer.hpp).
//
// named_track collects what the stream carries (the header's names, the
// frames, the server's ARKit weights, else the built-in retargeting when the
// channels are the built-in model's); write_named_track hands it to core's
// lipsync::write_track as a NamedTrackView, the writer `lipsync render` uses,
// so the layouts and number formats cannot drift apart.
#include "received_track_writer.hpp"

#include <iostream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cli_error.hpp"
#include "files.hpp"
#include "lipsync/error.hpp"
#include "lipsync/model.hpp"

namespace lipsync::cli {
namespace {

/// Whether `names` are the built-in model's channels, in its order.
bool are_builtin_channels(const google::protobuf::RepeatedPtrField<std::string>& names) {
  const ArticulationModel& builtin = ArticulationModel::builtin();
  if (static_cast<std::size_t>(names.size()) != builtin.channel_count()) return false;
  for (std::size_t c = 0; c < builtin.channel_count(); ++c) {
    if (names[static_cast<int>(c)] != builtin.channels()[c].name) return false;
  }
  return true;
}

}  // namespace

NamedTrack named_track(const client::ReceivedTrack& received, TrackFormat format, const std::string& source) {
  const client::v1::TrackHeader& header = received.header;
  if (header.channels().empty() && format != TrackFormat::arkit_csv) {
    throw InputError(source, 0,
                     "the track carries no channel values (only ARKit weights), so it cannot be written as " +
                         std::string(to_string(format)) + " (use --format " +
                         std::string(to_string(TrackFormat::arkit_csv)) + ")");
  }
  NamedTrack named;
  named.model = header.model();
  named.channel_names.assign(header.channels().begin(), header.channels().end());
  named.track = received.track;
  if (!header.arkit_names().empty()) {
    named.arkit_names.assign(header.arkit_names().begin(), header.arkit_names().end());
    named.arkit = received.arkit;
  } else if (are_builtin_channels(header.channels())) {
    const ArticulationModel& builtin = ArticulationModel::builtin();
    named.arkit_names.assign(kArkitNames.begin(), kArkitNames.end());
    named.arkit.resize(named.track.frame_count() * kArkitNames.size());
    for (std::size_t f = 0; f < named.track.frame_count(); ++f) {
      builtin.retarget_to_arkit(named.track.frame_values(f),
                                std::span<float>(named.arkit).subspan(f * kArkitNames.size(), kArkitNames.size()));
    }
  } else if (format == TrackFormat::arkit_csv) {
    throw InputError(source, 0,
                     "the track carries no ARKit weights and its model '" + header.model() +
                         "' is not the built-in one, so it cannot be written as " +
                         std::string(to_string(TrackFormat::arkit_csv)));
  }
  return named;
}

void write_named_track(const NamedTrack& track, TrackFormat format, std::ostream& out) {
  const std::vector<std::string_view> channel_names(track.channel_names.begin(), track.channel_names.end());
  const std::vector<std::string_view> arkit_names(track.arkit_names.begin(), track.arkit_names.end());
  write_track(NamedTrackView{.model = track.model,
                             .channel_names = channel_names,
                             .arkit_names = arkit_names,
                             .track = track.track,
                             .arkit = track.arkit},
              format, out);
}

void write_received_track(const client::ReceivedTrack& received, TrackFormat format, const std::string& output,
                          const std::string& source) {
  const NamedTrack named = named_track(received, format, source);
  write_to_output(output, "track", [&](std::ostream& out) { write_named_track(named, format, out); });
}

}  // namespace lipsync::cli
