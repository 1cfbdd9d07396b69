// What the network commands (stream, speak, subscribe, play, loadtest, server-models)
// share: the --server option, the loopback check and the clocks; the
// --server-model and --session options of the commands that produce a track. Received
// tracks are written by received_track_writer.hpp.
#pragma once

#include <string>
#include <string_view>

#include "arguments.hpp"
#include "lipsync/client/animation_client.hpp"
#include "lipsync/track_writer.hpp"

namespace lipsync::cli {

inline constexpr std::string_view kDefaultServer = "127.0.0.1:50051";

inline constexpr OptionSpec kServerOption = {"server", 0, "ADDR", "lipsyncd address, HOST:PORT",
                                             kDefaultServer};

inline constexpr OptionSpec kServerModelOption = {"server-model", 0, "NAME",
    "the server's model to animate with (see 'lipsync server-models'); the output is named after its channels",
    "the server's default model"};
inline constexpr OptionSpec kSessionOption = {"session", 0, "NAME",
    "publish the frames under this session name for subscribers", "private"};

/// Into `settings`: the outputs a track written in `format` needs (channels, and the
/// server's ARKit weights unless csv), --server-model and --session (UsageError if empty).
void set_track_request_options(const Arguments& arguments, TrackFormat format,
                               client::v1::AnimationSettings& settings);

/// --server, checked to be non-empty.
std::string server_address(const Arguments& arguments);

/// Whether `address` names this machine (127.x.y.z, localhost, [::1], unix:).
bool is_loopback_address(std::string_view address);

/// Microseconds on the wall clock (the "unix" media clock) and on the steady clock.
std::int64_t unix_now_us();
std::int64_t steady_now_us();

}  // namespace lipsync::cli
