// What the network commands (stream, subscribe, play, loadtest, server-models)
// share: the --server option, the loopback check and the clocks. Received
// tracks are written by received_track_writer.hpp.
#pragma once

#include <string>
#include <string_view>

#include "arguments.hpp"
#include "lipsync/client/animation_client.hpp"

namespace lipsync::cli {

inline constexpr std::string_view kDefaultServer = "127.0.0.1:50051";

inline constexpr OptionSpec kServerOption = {"server", 0, "ADDR", "lipsyncd address, HOST:PORT",
                                             kDefaultServer};

/// --server, checked to be non-empty.
std::string server_address(const Arguments& arguments);

/// Whether `address` names this machine (127.x.y.z, localhost, [::1], unix:).
bool is_loopback_address(std::string_view address);

/// Microseconds on the wall clock (the "unix" media clock) and on the steady clock.
std::int64_t unix_now_us();
std::int64_t steady_now_us();

}  // namespace lipsync::cli
