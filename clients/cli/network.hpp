// What the network commands (stream, subscribe, play, loadtest) share: the
// --server option, turning received tracks into core Tracks for the writers,
// and the settings sent to lipsyncd.
#pragma once

#include <string>
#include <string_view>

#include "arguments.hpp"
#include "lipsync/client/animation_client.hpp"
#include "lipsync/model.hpp"

namespace lipsync::cli {

inline constexpr std::string_view kDefaultServer = "127.0.0.1:50051";

inline constexpr OptionSpec kServerOption = {"server", 0, "ADDR", "lipsyncd address, HOST:PORT",
                                             kDefaultServer};

/// --server, checked to be non-empty.
std::string server_address(const Arguments& arguments);

/// Whether `address` names this machine (127.x.y.z, localhost, [::1], unix:).
bool is_loopback_address(std::string_view address);

/// The received frames as a Track for the writers of `model`. Throws
/// InputError naming `source` when the track carries no channel values or
/// its channels are not the model's.
Track track_for_writing(const client::ReceivedTrack& received, const ArticulationModel& model,
                        const std::string& source);

/// Microseconds on the wall clock (the "unix" media clock) and on the steady clock.
std::int64_t unix_now_us();
std::int64_t steady_now_us();

}  // namespace lipsync::cli
