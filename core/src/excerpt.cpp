// Short, safe excerpts of client values (lipsync/excerpt.hpp).
#include "lipsync/excerpt.hpp"

#include <cstdint>

namespace lipsync {
namespace {

/// Length of the valid UTF-8 sequence starting at `at`, or 0 if none starts there.
std::size_t utf8_length(std::string_view text, std::size_t at) {
  const auto byte = static_cast<unsigned char>(text[at]);
  std::size_t length = 0;
  std::uint32_t min = 0;
  if (byte >= 0xC2 && byte <= 0xDF) {
    length = 2;
    min = 0x80;
  } else if (byte >= 0xE0 && byte <= 0xEF) {
    length = 3;
    min = 0x800;
  } else if (byte >= 0xF0 && byte <= 0xF4) {
    length = 4;
    min = 0x10000;
  } else {
    return 0;
  }
  if (at + length > text.size()) return 0;
  std::uint32_t code = byte & (0x7Fu >> length);
  for (std::size_t i = 1; i < length; ++i) {
    const auto next = static_cast<unsigned char>(text[at + i]);
    if ((next & 0xC0) != 0x80) return 0;
    code = (code << 6) | (next & 0x3Fu);
  }
  if (code < min || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return 0;
  return length;
}

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
      const std::size_t length = utf8_length(value, at);
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
