// Writing the frames lipsyncd sent, named as the server names them.
//
// A server may animate with a model the client does not have (`lipsyncd
// --model NAME=FILE`): its channels, and the linear map from them to the ARKit
// weights, are known only to the server. So the network commands write what
// the stream's TrackHeader says (model name, channel names, ARKit names) and
// the ARKit weights the server computed, never the built-in model's names.
//
// The writer is lipsync::write_track itself (docs/output-formats.md), given
// these names and weights as a NamedTrackView: for a track of the built-in
// model the output equals `lipsync render`'s byte for byte
// (tests/clients/network_cli_test.cpp pins that for every format).
// When the stream carries no ARKit weights (a producer that asked for channels
// only) and its channels are the built-in model's, the weights are computed
// locally with the built-in retargeting, as the server would have.
#pragma once

#include <ostream>
#include <string>
#include <vector>

#include "lipsync/client/animation_client.hpp"
#include "lipsync/track.hpp"
#include "lipsync/track_writer.hpp"

namespace lipsync::cli {

/// A track with the names that go with its values.
struct NamedTrack {
  std::string model;                       ///< the server's model name
  std::vector<std::string> channel_names;  ///< one per track channel
  std::vector<std::string> arkit_names;    ///< empty when there are no ARKit weights
  Track track;
  std::vector<float> arkit;  ///< frame_count() × arkit_names.size()
};

/// The received frames with the header's names. ARKit weights: the server's,
/// else the built-in retargeting when the channels are the built-in model's,
/// else none. Throws InputError naming `source` when the stream carries no
/// channel values, or when `format` needs ARKit weights and there are none.
NamedTrack named_track(const client::ReceivedTrack& received, TrackFormat format, const std::string& source);

/// Writes `track` in `format` with lipsync::write_track, through a NamedTrackView.
void write_named_track(const NamedTrack& track, TrackFormat format, std::ostream& out);

/// named_track, then write_named_track to `output` ("-" for standard output),
/// all or nothing. Throws InputError or FileError.
void write_received_track(const client::ReceivedTrack& received, TrackFormat format, const std::string& output,
                          const std::string& source);

}  // namespace lipsync::cli
