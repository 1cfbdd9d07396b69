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

/// What the phonemes say about a frame, whatever its channel values show: which closure holds the
/// lips there, and whether it lies in a pause. The renderer knows it (the frame's segment and its
/// neighbours); the viseme layer reads it (visemes.hpp, "Known shapes").
struct FrameArticulation {
  static constexpr std::int32_t kNoPhoneme = -1;
  static constexpr std::int64_t kNotInPause = -1;
  /// Model phoneme index of the /p b m f v/ closure (PhonemeClass::closure) whose hold
  /// [start, end] contains the frame time, or kNoPhoneme. Where two closures meet at the frame
  /// (the end of /v/ and the start of /m/ in "of my"), `closure` is the earlier one and
  /// `meeting_closure` the later one.
  std::int32_t closure = kNoPhoneme;
  std::int32_t meeting_closure = kNoPhoneme;
  /// In a silence segment: the time from the frame to the nearest speech the renderer's window holds
  /// (the end of the speech before it, the start of the speech after it), µs; INT64_MAX when there is
  /// none on either side (a leading pause with no speech known after it yet, a trailing one).
  /// kNotInPause elsewhere.
  std::int64_t pause_us = kNotInPause;
  bool operator==(const FrameArticulation&) const = default;
};

struct Track {
  std::size_t channel_count = 0;
  int fps = 30;
  std::vector<std::int64_t> t_us;  ///< frame times, strictly increasing
  std::vector<FrameKind> kinds;
  std::vector<float> values;  ///< frame_count() × channel_count
  /// One per frame from the renderers; empty in a track built by hand (nothing known).
  std::vector<FrameArticulation> articulation;

  std::size_t frame_count() const { return t_us.size(); }
  std::span<const float> frame_values(std::size_t frame) const {
    return {values.data() + frame * channel_count, channel_count};
  }
  void clear() {
    t_us.clear();
    kinds.clear();
    values.clear();
    articulation.clear();
  }
  /// Room for `frames` frames (of channel_count values each) without reallocating.
  void reserve(std::size_t frames) {
    t_us.reserve(frames);
    kinds.reserve(frames);
    values.reserve(frames * channel_count);
    articulation.reserve(frames);
  }
  /// The frame's articulation, or nothing known when the track carries none.
  FrameArticulation frame_articulation(std::size_t frame) const {
    return frame < articulation.size() ? articulation[frame] : FrameArticulation{};
  }
};

}  // namespace lipsync
