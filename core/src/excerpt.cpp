// Short, safe excerpts of client values (lipsync/excerpt.hpp).
#include "lipsync/excerpt.hpp"

#include <cstdint>

#include "formats/text.hpp"

namespace lipsync {
namespace {

void append_escaped_byte(std::string& out, unsigned char byte) {
  static constexpr char kHex[] = "0123456789abcdef";
  out += "\\x";
  out += kHex[byte >> 4];
  out += kHex[byte & 0xF];
}

}  // namespace

std::string excerpt(std::string_view value) {
  const bool cut = value.size() > kExcerptBytes;
  const std::size_t keep = cut ? kExcerptBytes - 16 : value.size();  // room for " (N bytes)"
  std::string out = "'";
  std::size_t at = 0;
  while (at < keep) {
    const auto byte = static_cast<unsigned char>(value[at]);
    if (byte >= 0x80) {
      const std::size_t length = formats::utf8_sequence_length(value, at);
      if (length > 0 && at + length <= keep) {
        out.append(value.substr(at, length));
        at += length;
        continue;
      }
      if (length > 0) break;  // a whole character does not fit: cut before it
      append_escaped_byte(out, byte);
    } else if (byte < 0x20 || byte == 0x7F || byte == '\'' || byte == '\\') {
      append_escaped_byte(out, byte);
    } else {
      out += static_cast<char>(byte);
    }
    ++at;
  }
  if (!cut) return out + "'";
  return out + "…' (" + std::to_string(value.size()) + " bytes)";
}

}  // namespace lipsync
