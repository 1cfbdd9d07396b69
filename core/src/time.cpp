// Exact conversions between decimal seconds and integer microseconds.
//
// Decimal text is converted digit by digit (no binary floating point in
// between), so "0.171" is exactly 171000 µs and "0.0000005" rounds to 1 µs
// (half away from zero). Exponents are applied by shifting the decimal point.
#include "lipsync/time.hpp"

#include <cmath>
#include <cstdlib>

namespace lipsync {

std::string format_seconds(std::int64_t time_us) {
  const bool negative = time_us < 0;
  // Work with the magnitude as unsigned to survive INT64_MIN.
  const std::uint64_t magnitude =
      negative ? 0 - static_cast<std::uint64_t>(time_us) : static_cast<std::uint64_t>(time_us);
  const std::string fraction = std::to_string(magnitude % 1'000'000);
  std::string text;
  text.reserve(24);
  if (negative) text.push_back('-');
  text.append(std::to_string(magnitude / 1'000'000));
  text.push_back('.');
  text.append(6 - fraction.size(), '0');
  text.append(fraction);
  return text;
}

std::optional<std::int64_t> seconds_to_us(double seconds) {
  if (!std::isfinite(seconds)) return std::nullopt;
  const double micros = std::round(seconds * 1e6);
  if (std::fabs(micros) > static_cast<double>(kMaxTimeUs)) return std::nullopt;
  return static_cast<std::int64_t>(micros);
}

std::optional<std::int64_t> parse_seconds_to_us(std::string_view text) {
  std::size_t pos = 0;
  bool negative = false;
  if (pos < text.size() && (text[pos] == '+' || text[pos] == '-')) {
    negative = text[pos] == '-';
    ++pos;
  }
  // Collect the significant digits and where the decimal point sits.
  std::string digits;
  int point_shift = 0;  // value = digits × 10^(point_shift)
  bool seen_digit = false;
  bool seen_point = false;
  for (; pos < text.size(); ++pos) {
    const char ch = text[pos];
    if (ch >= '0' && ch <= '9') {
      seen_digit = true;
      if (digits.empty() && ch == '0') {
        if (seen_point) --point_shift;
        continue;  // leading zero
      }
      if (digits.size() < 40) {
        digits.push_back(ch);
        if (seen_point) --point_shift;
      } else if (!seen_point) {
        ++point_shift;  // beyond our precision: huge, rejected below
      }
    } else if (ch == '.' && !seen_point) {
      seen_point = true;
    } else {
      break;
    }
  }
  if (!seen_digit) return std::nullopt;
  if (pos < text.size() && (text[pos] == 'e' || text[pos] == 'E')) {
    ++pos;
    bool exponent_negative = false;
    if (pos < text.size() && (text[pos] == '+' || text[pos] == '-')) {
      exponent_negative = text[pos] == '-';
      ++pos;
    }
    if (pos >= text.size()) return std::nullopt;
    int exponent = 0;
    for (; pos < text.size(); ++pos) {
      const char ch = text[pos];
      if (ch < '0' || ch > '9') return std::nullopt;
      if (exponent < 10000) exponent = exponent * 10 + (ch - '0');
    }
    point_shift += exponent_negative ? -exponent : exponent;
  }
  if (pos != text.size()) return std::nullopt;
  if (digits.empty()) return 0;

  // Microseconds = digits × 10^(point_shift + 6), rounded half away from zero.
  const int shift = point_shift + 6;
  const int integer_digits = static_cast<int>(digits.size()) + shift;
  if (integer_digits > 15) return std::nullopt;  // > 10^15 µs, far beyond kMaxTimeUs
  std::int64_t micros = 0;
  for (int i = 0; i < integer_digits; ++i) {
    const char ch = i < static_cast<int>(digits.size()) ? digits[static_cast<std::size_t>(i)] : '0';
    micros = micros * 10 + (ch - '0');
  }
  if (integer_digits >= 0 && integer_digits < static_cast<int>(digits.size()) &&
      digits[static_cast<std::size_t>(integer_digits)] >= '5') {
    ++micros;
  }
  if (micros > kMaxTimeUs) return std::nullopt;
  return negative ? -micros : micros;
}

}  // namespace lipsync
