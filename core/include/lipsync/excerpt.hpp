// Client values echoed in error messages and logs, cut to a short, safe excerpt.
//
// A label, a model or phone-set name, a session name: whatever a client sent may be
// megabytes long or hold control characters. Echoed whole, it would make a status
// bigger than a client's metadata limit (the client then sees RESOURCE_EXHAUSTED
// "received initial metadata size exceeds limit" instead of the real error) and
// fill the log. Every message that echoes a value passes it through `excerpt`:
// short values come back quoted as they were; long ones are cut at a UTF-8
// character boundary and say how long they were; control bytes and invalid UTF-8
// are written as \xNN, so a log line stays one line.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace lipsync {

/// Longest value echoed whole, in bytes; longer values are cut to about this many.
inline constexpr std::size_t kExcerptBytes = 64;

/// `value` quoted for a message: 'abc' when it is at most kExcerptBytes bytes long,
/// else 'its first bytes…' (N bytes). Control bytes, quotes and backslashes and bytes
/// that are not valid UTF-8 are written as \xNN (valid UTF-8 letters stay as they are).
std::string excerpt(std::string_view value);

}  // namespace lipsync
