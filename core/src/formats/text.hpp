// Text helpers shared by the format readers: decoding to UTF-8, splitting into
// numbered lines and fields, and turning a time field into microseconds with an
// InputError that names the field and shows the offending text.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lipsync::formats {

/// One line of a file without its line break; `number` is 1-based.
struct Line {
  std::string_view text;
  int number = 0;
};

/// Decodes `content` to UTF-8: strips a UTF-8 BOM, decodes UTF-16 BE/LE with a
/// BOM, and rejects bytes that are not UTF-8 with the line they are on.
std::string decode_to_utf8(std::string_view content, std::string_view source);

/// Splits at "\n", "\r\n" and "\r" (Praat allows all three).
std::vector<Line> split_lines(std::string_view text);

/// Splits at runs of spaces and tabs.
std::vector<std::string_view> split_fields(std::string_view text);

std::string_view trim(std::string_view text);

/// Length of the valid UTF-8 sequence at text[i] (1 for ASCII), or 0 if it is not valid.
std::size_t utf8_sequence_length(std::string_view text, std::size_t i);

/// `text` in double quotes for a message, shortened to about 60 bytes on a UTF-8
/// character boundary, control characters escaped.
std::string excerpt(std::string_view text);

/// Plain decimal syntax: [+-] digits [. digits] [e [+-] digits] (either side of
/// the point may be empty, not both).
bool is_decimal_number(std::string_view text);

/// "nan", "inf", "-infinity", Praat's "--undefined--" and the like.
bool is_non_finite_word(std::string_view text);

/// Non-negative integer in plain decimal digits (a leading '+' is allowed);
/// nullopt if not one or larger than `max_value`.
std::optional<std::int64_t> parse_count(std::string_view text, std::int64_t max_value);

/// A finite number in decimal syntax, as a double (for values we only check).
std::optional<double> parse_finite_double(std::string_view text);

/// A time in seconds written as decimal text, exact to the nearest µs. Throws
/// InputError(source, line, ...) naming `field` and the text when it is not a
/// number, not finite, negative, or beyond kMaxTimeUs.
std::int64_t seconds_field_to_us(std::string_view text, std::string_view field, const std::string& source, int line);

/// Same checks for a non-negative decimal count of milliseconds.
std::int64_t milliseconds_field_to_us(std::string_view text, std::string_view field, const std::string& source,
                                      int line);

/// Sum of two times that must stay within kMaxTimeUs (accumulated durations).
std::int64_t checked_add_us(std::int64_t a_us, std::int64_t b_us, const std::string& source, int line);

}  // namespace lipsync::formats
