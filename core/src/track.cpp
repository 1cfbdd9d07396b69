#include "lipsync/track.hpp"

namespace lipsync {

std::string_view to_string(FrameKind kind) {
  switch (kind) {
    case FrameKind::uniform:
      return "uniform";
    case FrameKind::closure_start:
      return "closure_start";
    case FrameKind::closure_end:
      return "closure_end";
    case FrameKind::short_segment:
      return "short_segment";
  }
  return "?";
}

std::optional<FrameKind> frame_kind_from_string(std::string_view name) {
  for (auto kind : {FrameKind::uniform, FrameKind::closure_start, FrameKind::closure_end, FrameKind::short_segment}) {
    if (to_string(kind) == name) return kind;
  }
  return std::nullopt;
}

}  // namespace lipsync
