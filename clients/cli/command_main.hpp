// How a command-line program of lipsync ends: every failure of its command as
// one line on stderr and an exit status (0 success, 1 bad input, a file or a
// call that failed, 2 a mistake on the command line), then the process ends
// once its output is flushed. `lipsync` and the load generator (tools/loadtest)
// both end this way.
#pragma once

#include <functional>

namespace lipsync::cli {

/// Runs `command` and returns its status; a failure it throws becomes one line
/// on stderr ("lipsync: error: ...") and the status its kind calls for.
int report_failures(const std::function<int()>& command);

/// Ends the process with `status` once stdout and stderr are flushed, without
/// exit handlers.
///
/// gRPC's threads may still be busy with a connection the command has given up
/// on (a TLS handshake retried after --timeout, say) while the exit handlers
/// run, and OpenSSL's frees what such a thread uses. Everything the command
/// wrote is closed by now (its files by their writers, stdout and stderr here),
/// and lipsyncd ends the same way (server/src/main.cpp). Under ASan the leak
/// check that an exit handler would make is made here; under TSan a report ends
/// the process at once (halt_on_error, as deploy/sanitize.sh runs it).
[[noreturn]] void end_process(int status);

}  // namespace lipsync::cli
