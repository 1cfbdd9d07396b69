// Time in lipsyncd is an integer count of microseconds everywhere it is stored,
// sent or written (`*_us` fields). Floating seconds exist only inside the
// dominance arithmetic, converted at the last moment.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace lipsync {

inline constexpr std::int64_t kMicrosPerSecond = 1'000'000;

/// The longest time any input may name: 24 hours. Later times are "absurd"
/// (almost always a unit mistake: samples or milliseconds read as seconds).
inline constexpr std::int64_t kMaxTimeUs = 24LL * 3600 * kMicrosPerSecond;

/// Exact decimal seconds with six fractional digits: 1234567 -> "1.234567",
/// -5 -> "-0.000005".
std::string format_seconds(std::int64_t time_us);

/// Parses a decimal number of seconds ("0.171", "1e-3", "12") and rounds it to
/// the nearest microsecond. Returns nullopt for text that is not a finite
/// number or whose magnitude exceeds kMaxTimeUs.
std::optional<std::int64_t> parse_seconds_to_us(std::string_view text);

/// `seconds` rounded to the nearest microsecond; nullopt if not finite or
/// beyond kMaxTimeUs in magnitude.
std::optional<std::int64_t> seconds_to_us(double seconds);

inline double to_seconds(std::int64_t time_us) { return static_cast<double>(time_us) * 1e-6; }

}  // namespace lipsync
