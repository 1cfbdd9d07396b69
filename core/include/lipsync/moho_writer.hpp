// Moho switch data (`--format moho-dat`): the "MohoSwitch1" file that Papagayo and Rhubarb Lip Sync
// write for Moho's (Anime Studio's) switch layers and OpenToonz's lip-sync data, in the ten Preston
// Blair mouth names (docs/output-formats.md, "moho-dat").
//
// The layout is a header line and one line per change of mouth, frames numbered from 1 at the
// project's frame rate:
//
//   MohoSwitch1
//   1 rest
//   5 MBP
//   7 etc
//   8 AI
//   ...
//   50 rest
//
// The mouths come from the Rhubarb viseme layer (visemes.hpp: A–H and X, computed from the
// coarticulated channels), renamed as Rhubarb's own `--datUsePrestonBlair` renames them: A MBP, B etc,
// C E, D AI, E O, F U, G FV, H L, X rest. WQ is one of the ten names but is never written: every
// viseme vocabulary gives /w/ the shape of /uw/ (Rhubarb's F, hence U), as Rhubarb does.
//
// Which mouth a frame shows. Frame n (numbered from 1) is on screen from (n − 1) / fps. A track frame
// at t belongs to the Moho frame nearest to it, round(t · fps) + 1 (half up, in integer µs), and a
// Moho frame shows the mouth of the last track frame that belongs to it or to an earlier one. A
// closure key frame (closure_start, closure_end) takes precedence in the Moho frame it belongs to:
// that frame shows its mouth (MBP before any other when several closures meet there), so a /p b m/
// whose release falls in the same frame as an opening mouth still shuts the lips on its frame, which
// sampling alone would skip. The last line is the first frame at or after the end of the utterance,
// with the rest mouth (it marks the end, so it may repeat the mouth before it).
#pragma once

#include <array>
#include <cstdint>
#include <ostream>
#include <string_view>
#include <vector>

#include "lipsync/named_format.hpp"
#include "lipsync/viseme_writer.hpp"

namespace lipsync {

/// Switch data is a format of its own beside the track and viseme formats.
enum class MouthSwitchFormat { moho_dat };
inline constexpr std::array<NamedFormat<MouthSwitchFormat>, 1> kMouthSwitchFormats{{
    {MouthSwitchFormat::moho_dat, "moho-dat", "Moho/OpenToonz/Papagayo switch data, Preston Blair mouths"},
}};

/// Moho frame rates accepted (frames per second, whole numbers).
inline constexpr int kMinMohoFps = 1;
inline constexpr int kMaxMohoFps = 1000;

/// The Preston Blair mouth of a Rhubarb shape ("A" → "MBP", … "X" → "rest"); empty for another name.
std::string_view preston_blair_mouth(std::string_view rhubarb_shape);

/// One line of switch data: from `frame` (numbered from 1) on, the mouth `mouth`.
struct MohoKey {
  std::int64_t frame = 1;
  std::string_view mouth;  ///< a Preston Blair name ("AI", "E", "O", "U", "etc", "L", "WQ", "MBP", "FV", "rest")
  bool operator==(const MohoKey&) const = default;
};

/// The switch keys of `view` (a Rhubarb classifier's visemes) at `fps` frames per second, the last
/// one the rest mouth at the end. Throws std::invalid_argument for another vocabulary, an `fps`
/// outside [kMinMohoFps, kMaxMohoFps], or arrays that disagree in size.
std::vector<MohoKey> moho_keys(const VisemeTrackView& view, int fps);

/// Writes "MohoSwitch1" and the keys, one "FRAME MOUTH" line each ('\n' line ends).
void write_moho_switch(const VisemeTrackView& view, int fps, std::ostream& out);

}  // namespace lipsync
