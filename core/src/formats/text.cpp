// Text helpers for the format readers (see text.hpp).
//
// Every reader first gets the file as UTF-8 (decode_to_utf8), so labels are
// always valid UTF-8 downstream (JSON output and protobuf strings require it).
// Numbers are checked for syntax here, then converted exactly by the decimal
// routines of lipsync/time.hpp: no binary floating point between the text and
// the microseconds.
#include "formats/text.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>
#include <system_error>

#include "lipsync/error.hpp"
#include "lipsync/time.hpp"

namespace lipsync::formats {
namespace {

constexpr std::size_t kExcerptBytes = 60;

bool is_digit(char ch) { return ch >= '0' && ch <= '9'; }

bool is_blank(char ch) { return ch == ' ' || ch == '\t' || ch == '\v' || ch == '\f'; }

// Line number of byte `offset` in UTF-8 text with any of the three line breaks.
int line_at(std::string_view text, std::size_t offset) {
  int line = 1;
  for (std::size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n' || (text[i] == '\r' && (i + 1 >= text.size() || text[i + 1] != '\n'))) {
      ++line;
    }
  }
  return line;
}

void append_utf8(std::string& out, std::uint32_t code_point) {
  if (code_point < 0x80) {
    out.push_back(static_cast<char>(code_point));
  } else if (code_point < 0x800) {
    out.push_back(static_cast<char>(0xC0 | (code_point >> 6)));
    out.push_back(static_cast<char>(0x80 | (code_point & 0x3F)));
  } else if (code_point < 0x10000) {
    out.push_back(static_cast<char>(0xE0 | (code_point >> 12)));
    out.push_back(static_cast<char>(0x80 | ((code_point >> 6) & 0x3F)));
    out.push_back(static_cast<char>(0x80 | (code_point & 0x3F)));
  } else {
    out.push_back(static_cast<char>(0xF0 | (code_point >> 18)));
    out.push_back(static_cast<char>(0x80 | ((code_point >> 12) & 0x3F)));
    out.push_back(static_cast<char>(0x80 | ((code_point >> 6) & 0x3F)));
    out.push_back(static_cast<char>(0x80 | (code_point & 0x3F)));
  }
}

std::string decode_utf16(std::string_view bytes, bool big_endian, std::string_view source) {
  if (bytes.size() % 2 != 0) {
    throw InputError(std::string(source), 0,
                     "UTF-16 file (it starts with a byte order mark) has an odd number of bytes; "
                     "it is truncated or not UTF-16");
  }
  std::string out;
  out.reserve(bytes.size() / 2);
  int line = 1;
  auto unit_at = [&](std::size_t i) {
    const auto b0 = static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i]));
    const auto b1 = static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 1]));
    return big_endian ? (b0 << 8) | b1 : (b1 << 8) | b0;
  };
  for (std::size_t i = 0; i < bytes.size(); i += 2) {
    std::uint32_t unit = unit_at(i);
    if (unit >= 0xD800 && unit <= 0xDBFF) {
      const std::uint32_t low = i + 3 < bytes.size() ? unit_at(i + 2) : 0;
      if (low < 0xDC00 || low > 0xDFFF) {
        throw InputError(std::string(source), line, "UTF-16 text has an unpaired high surrogate");
      }
      unit = 0x10000 + ((unit - 0xD800) << 10) + (low - 0xDC00);
      i += 2;
    } else if (unit >= 0xDC00 && unit <= 0xDFFF) {
      throw InputError(std::string(source), line, "UTF-16 text has an unpaired low surrogate");
    }
    if (unit == '\n') ++line;
    append_utf8(out, unit);
  }
  return out;
}

std::string lowercase(std::string_view text) {
  std::string out(text);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](char ch) { return static_cast<char>(std::tolower(static_cast<unsigned char>(ch))); });
  return out;
}

}  // namespace

// Length of the valid UTF-8 sequence at text[i], or 0 if it is not valid.
std::size_t utf8_sequence_length(std::string_view text, std::size_t i) {
  const auto lead = static_cast<unsigned char>(text[i]);
  if (lead < 0x80) return 1;
  std::size_t length = 0;
  std::uint32_t min_value = 0;
  std::uint32_t value = 0;
  if ((lead & 0xE0) == 0xC0) {
    length = 2, min_value = 0x80, value = lead & 0x1Fu;
  } else if ((lead & 0xF0) == 0xE0) {
    length = 3, min_value = 0x800, value = lead & 0x0Fu;
  } else if ((lead & 0xF8) == 0xF0) {
    length = 4, min_value = 0x10000, value = lead & 0x07u;
  } else {
    return 0;
  }
  if (i + length > text.size()) return 0;
  for (std::size_t k = 1; k < length; ++k) {
    const auto next = static_cast<unsigned char>(text[i + k]);
    if ((next & 0xC0) != 0x80) return 0;
    value = (value << 6) | (next & 0x3Fu);
  }
  if (value < min_value || value > 0x10FFFF || (value >= 0xD800 && value <= 0xDFFF)) return 0;
  return length;
}

std::string decode_to_utf8(std::string_view content, std::string_view source) {
  std::string text;
  if (content.starts_with("\xEF\xBB\xBF")) {
    text = std::string(content.substr(3));
  } else if (content.starts_with("\xFE\xFF")) {
    return decode_utf16(content.substr(2), /*big_endian=*/true, source);
  } else if (content.starts_with("\xFF\xFE")) {
    return decode_utf16(content.substr(2), /*big_endian=*/false, source);
  } else {
    text = std::string(content);
  }
  for (std::size_t i = 0; i < text.size();) {
    const std::size_t length = utf8_sequence_length(text, i);
    if (length == 0) {
      char byte[8];
      std::snprintf(byte, sizeof byte, "0x%02X", static_cast<unsigned char>(text[i]));
      throw InputError(std::string(source), line_at(text, i),
                       std::string("text is not valid UTF-8 (byte ") + byte +
                           "); save the file as UTF-8, or as UTF-16 with a byte order mark");
    }
    i += length;
  }
  return text;
}

std::vector<Line> split_lines(std::string_view text) {
  std::vector<Line> lines;
  int number = 1;
  std::size_t start = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] != '\n' && text[i] != '\r') continue;
    lines.push_back({text.substr(start, i - start), number++});
    if (text[i] == '\r' && i + 1 < text.size() && text[i + 1] == '\n') ++i;
    start = i + 1;
  }
  if (start < text.size()) lines.push_back({text.substr(start), number});
  return lines;
}

std::vector<std::string_view> split_fields(std::string_view text) {
  std::vector<std::string_view> fields;
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && is_blank(text[i])) ++i;
    const std::size_t start = i;
    while (i < text.size() && !is_blank(text[i])) ++i;
    if (i > start) fields.push_back(text.substr(start, i - start));
  }
  return fields;
}

std::string_view trim(std::string_view text) {
  auto is_space = [](char ch) { return is_blank(ch) || ch == '\n' || ch == '\r'; };
  while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
  while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
  return text;
}

std::string excerpt(std::string_view text) {
  bool shortened = false;
  if (text.size() > kExcerptBytes) {
    std::size_t cut = kExcerptBytes - 3;
    while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;
    text = text.substr(0, cut);
    shortened = true;
  }
  std::string out = "\"";
  for (const char ch : text) {
    const auto byte = static_cast<unsigned char>(ch);
    if (ch == '\t') {
      out += "\\t";
    } else if (byte < 0x20 || byte == 0x7F) {
      char escaped[8];
      std::snprintf(escaped, sizeof escaped, "\\x%02X", byte);
      out += escaped;
    } else {
      out.push_back(ch);
    }
  }
  if (shortened) out += "...";
  return out + "\"";
}

bool is_decimal_number(std::string_view text) {
  std::size_t i = 0;
  if (i < text.size() && (text[i] == '+' || text[i] == '-')) ++i;
  std::size_t digits = 0;
  while (i < text.size() && is_digit(text[i])) ++i, ++digits;
  if (i < text.size() && text[i] == '.') {
    ++i;
    while (i < text.size() && is_digit(text[i])) ++i, ++digits;
  }
  if (digits == 0) return false;
  if (i < text.size() && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    if (i < text.size() && (text[i] == '+' || text[i] == '-')) ++i;
    std::size_t exponent_digits = 0;
    while (i < text.size() && is_digit(text[i])) ++i, ++exponent_digits;
    if (exponent_digits == 0) return false;
  }
  return i == text.size();
}

bool is_non_finite_word(std::string_view text) {
  std::string word = lowercase(text);
  if (word == "--undefined--") return true;
  if (!word.empty() && (word.front() == '+' || word.front() == '-')) word.erase(0, 1);
  return word == "nan" || word == "inf" || word == "infinity" || word == "undefined";
}

std::optional<std::int64_t> parse_count(std::string_view text, std::int64_t max_value) {
  if (text.starts_with('+')) text.remove_prefix(1);
  if (text.empty() || !std::all_of(text.begin(), text.end(), is_digit)) return std::nullopt;
  std::int64_t value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || value > max_value) {
    return std::nullopt;
  }
  return value;
}

std::optional<double> parse_finite_double(std::string_view text) {
  if (!is_decimal_number(text)) return std::nullopt;
  if (text.starts_with('+')) text.remove_prefix(1);
  double value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc() || end != text.data() + text.size() || !std::isfinite(value)) {
    return std::nullopt;
  }
  return value;
}

std::int64_t seconds_field_to_us(std::string_view text, std::string_view field, const std::string& source, int line) {
  const std::string what(field);
  if (!is_decimal_number(text)) {
    throw InputError(
        source, line,
        what + (is_non_finite_word(text) ? " is not a finite number: " : " is not a number: ") + excerpt(text));
  }
  const std::optional<std::int64_t> time_us = parse_seconds_to_us(text);
  if (!time_us) {
    if (text.starts_with('-')) throw InputError(source, line, what + " is negative: " + excerpt(text));
    throw InputError(source, line, what + " is beyond 24 hours: " + excerpt(text) + " (seconds expected)");
  }
  if (*time_us < 0) throw InputError(source, line, what + " is negative: " + excerpt(text));
  return *time_us;
}

std::int64_t milliseconds_field_to_us(std::string_view text, std::string_view field, const std::string& source,
                                      int line) {
  const std::string what(field);
  if (!is_decimal_number(text)) {
    throw InputError(
        source, line,
        what + (is_non_finite_word(text) ? " is not a finite number: " : " is not a number: ") + excerpt(text));
  }
  if (text.starts_with('-') && text.find_first_of("123456789") != std::string_view::npos) {
    throw InputError(source, line, what + " is negative: " + excerpt(text));
  }
  // Milliseconds are seconds × 10^-3: move the exponent, keeping the decimal exact.
  const std::string beyond = what + " is beyond 24 hours: " + excerpt(text) + " (milliseconds expected)";
  const std::size_t e = text.find_first_of("eE");
  std::int64_t exponent = -3;
  if (e != std::string_view::npos) {
    std::string_view written = text.substr(e + 1);
    const bool negative = written.starts_with('-');
    if (negative || written.starts_with('+')) written.remove_prefix(1);
    const std::optional<std::int64_t> magnitude = parse_count(written, 100'000);
    if (!magnitude) {
      if (negative) return 0;  // 10^-100000 ms and below
      throw InputError(source, line, beyond);
    }
    exponent += negative ? -*magnitude : *magnitude;
  }
  const std::string seconds = std::string(text.substr(0, e)) + "e" + std::to_string(exponent);
  const std::optional<std::int64_t> time_us = parse_seconds_to_us(seconds);
  if (!time_us) throw InputError(source, line, beyond);
  return *time_us < 0 ? 0 : *time_us;  // "-0"
}

std::int64_t checked_add_us(std::int64_t a_us, std::int64_t b_us, const std::string& source, int line) {
  if (b_us > kMaxTimeUs - a_us) {
    throw InputError(source, line,
                     "the durations so far add up to more than 24 hours (" + format_seconds(a_us) + " s + " +
                         format_seconds(b_us) + " s)");
  }
  return a_us + b_us;
}

}  // namespace lipsync::formats
