// A rendered animation track: frames with exact times, kinds and one value per
// model channel, stored frame-major in one flat array (no allocation per frame).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace lipsync {

/// Why a frame exists (paper Section 3.2 and 3.3).
enum class FrameKind : std::uint8_t {
  uniform,        ///< on the uniform sampling grid
  closure_start,  ///< start of a /p b m f v/ closure
  closure_end,    ///< end of a closure (release start or next phoneme start); the grid restarts here
  short_segment,  ///< peak of a segment that no other frame falls into
};

std::string_view to_string(FrameKind kind);
std::optional<FrameKind> frame_kind_from_string(std::string_view name);

struct Track {
  std::size_t channel_count = 0;
  int fps = 30;
  std::vector<std::int64_t> t_us;  ///< frame times, strictly increasing
  std::vector<FrameKind> kinds;
  std::vector<float> values;       ///< frame_count() × channel_count

  std::size_t frame_count() const { return t_us.size(); }
  std::span<const float> frame_values(std::size_t frame) const {
    return {values.data() + frame * channel_count, channel_count};
  }
  void clear() {
    t_us.clear();
    kinds.clear();
    values.clear();
  }
  /// Room for `frames` frames (of channel_count values each) without reallocating.
  void reserve(std::size_t frames) {
    t_us.reserve(frames);
    kinds.reserve(frames);
    values.reserve(frames * channel_count);
  }
};

}  // namespace lipsync
