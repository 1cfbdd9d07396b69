// Moho switch data from the Rhubarb viseme layer (the rules: lipsync/moho_writer.hpp).
//
// One pass over the track's frames: each frame is assigned to its nearest Moho frame; for every Moho
// frame the writer keeps the mouth held (the winner of the last track frame assigned at or before it)
// and the mouth of a closure key frame assigned to it, if any, which wins the frame. A line is
// written where the mouth shown changes. Times stay integer microseconds; a Moho frame index is
// round(t_us · fps / 10⁶) computed in 64-bit integers (exact for any utterance shorter than
// 2⁶³ / 10⁹ µs, about 292 years at 1000 fps).
#include "lipsync/moho_writer.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>
#include <utility>

namespace lipsync {
namespace {

// Rhubarb's DatExporter table (its --datUsePrestonBlair), one row per Rhubarb shape.
constexpr std::array<std::pair<std::string_view, std::string_view>, 9> kPrestonBlair = {{
    {"A", "MBP"},   // closed lips: p b m
    {"B", "etc"},   // clenched teeth: most consonants
    {"C", "E"},     // open: eh ae ah ey
    {"D", "AI"},    // wide open: aa ay aw
    {"E", "O"},     // slightly rounded: ao er r
    {"F", "U"},     // puckered: uw ow w uh oy (Preston Blair's WQ has no shape of its own here)
    {"G", "FV"},    // upper teeth on the lower lip: f v
    {"H", "L"},     // tongue raised: long l
    {"X", "rest"},  // idle
}};

constexpr std::string_view kRest = "rest";
constexpr std::string_view kClosed = "MBP";

/// The Moho frame (from 0) nearest to `t_us`, half up.
std::int64_t nearest_frame(std::int64_t t_us, int fps) { return (t_us * fps + 500'000) / 1'000'000; }

}  // namespace

std::string_view preston_blair_mouth(std::string_view rhubarb_shape) {
  for (const auto& [shape, mouth] : kPrestonBlair) {
    if (shape == rhubarb_shape) return mouth;
  }
  return {};
}

std::vector<MohoKey> moho_keys(const VisemeTrackView& view, int fps) {
  if (view.classifier.options().vocabulary != VisemeVocabulary::rhubarb) {
    throw std::invalid_argument("moho-dat needs rhubarb visemes, got " +
                                std::string(to_string(view.classifier.options().vocabulary)));
  }
  if (fps < kMinMohoFps || fps > kMaxMohoFps) {
    throw std::invalid_argument("moho-dat: frame rate " + std::to_string(fps) + " is outside [" +
                                std::to_string(kMinMohoFps) + ", " + std::to_string(kMaxMohoFps) + "]");
  }
  const Track& track = view.track;
  const std::size_t frames = track.frame_count();
  if (view.visemes.winners.size() != frames || track.kinds.size() != frames) {
    throw std::invalid_argument("moho-dat: viseme track disagrees with its track: " + std::to_string(frames) +
                                " frames, " + std::to_string(view.visemes.winners.size()) + " winners");
  }
  const auto& names = view.classifier.names();
  const auto mouth_of = [&](std::size_t f) {
    const std::string_view mouth = preston_blair_mouth(names[view.visemes.winners[f]]);
    return mouth.empty() ? kRest : mouth;
  };

  // Moho frames 0 … end_frame − 1 show the utterance (their instants k / fps lie before its end).
  const std::int64_t end_frame = std::max<std::int64_t>(0, (view.end_us * fps + 999'999) / 1'000'000);
  std::vector<MohoKey> keys;
  std::string_view held = kRest;  // the last track frame's mouth so far
  std::size_t f = 0;
  for (std::int64_t k = 0; k < end_frame; ++k) {
    std::string_view closure;  // the mouth of a closure key frame in this Moho frame, if any
    const bool last = k + 1 == end_frame;
    // The last Moho frame also takes the track frames that round beyond it, up to the end.
    for (; f < frames && track.t_us[f] <= view.end_us && (last || nearest_frame(track.t_us[f], fps) <= k); ++f) {
      held = mouth_of(f);
      const FrameKind kind = track.kinds[f];
      if ((kind == FrameKind::closure_start || kind == FrameKind::closure_end) && closure != kClosed) {
        if (closure.empty() || held == kClosed) closure = held;
      }
    }
    const std::string_view shown = closure.empty() ? held : closure;
    if (keys.empty() || keys.back().mouth != shown) keys.push_back({k + 1, shown});
  }
  keys.push_back({end_frame + 1, kRest});
  return keys;
}

void write_moho_switch(const VisemeTrackView& view, int fps, std::ostream& out) {
  std::string text = "MohoSwitch1\n";
  for (const MohoKey& key : moho_keys(view, fps)) {
    text += std::to_string(key.frame);
    text += ' ';
    text += key.mouth;
    text += '\n';
  }
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
}

}  // namespace lipsync
