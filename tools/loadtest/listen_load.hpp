// `lipsync loadtest --listen`: the load generator's audio mode (docs/performance.md, "Live audio").
#pragma once

#include "arguments.hpp"

namespace lipsync::cli {

/// Runs N live voices against a lipsyncd on this machine and prints the report; the exit status
/// (0: every stream ended OK with every frame, kExitInputError otherwise). Throws UsageError for
/// options the audio mode does not take.
int run_listen_load(const Arguments& arguments);

}  // namespace lipsync::cli
