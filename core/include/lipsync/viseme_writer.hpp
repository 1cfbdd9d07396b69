// Writers for the viseme layer (visemes.hpp), in the layouts engines already read
// (docs/output-formats.md, "Visemes"). They write to a stream; files are the caller's.
//
//   visemes-oculus  lipsync-visemes JSON: per frame the 15 OVRLipSync weights, plus events
//   visemes-azure   lipsync-visemes JSON: per frame the 22 weights, events with VisemeId and
//                   AudioOffset in 100-ns ticks, as Azure's VisemeReceived events carry them
//   visemes-polly   Amazon Polly viseme speech marks: JSON Lines {"time":ms,"type":"viseme","value":…}
//   rhubarb-tsv     Rhubarb Lip Sync's TSV: "0.00\tX" per mouth cue, then the end line
//   rhubarb-json    Rhubarb Lip Sync's JSON: {"metadata":{…},"mouthCues":[{start,end,value}]}
#pragma once

#include <cstdint>
#include <optional>
#include <ostream>
#include <string_view>
#include <vector>

#include "lipsync/named_format.hpp"
#include "lipsync/track.hpp"
#include "lipsync/visemes.hpp"

namespace lipsync {

enum class VisemeFormat { oculus, azure, polly, rhubarb_tsv, rhubarb_json };

/// The viseme formats by name, in the order help lists them.
inline constexpr std::array<NamedFormat<VisemeFormat>, 5> kVisemeFormats{{
    {VisemeFormat::oculus, "visemes-oculus"},
    {VisemeFormat::azure, "visemes-azure"},
    {VisemeFormat::polly, "visemes-polly"},
    {VisemeFormat::rhubarb_tsv, "rhubarb-tsv"},
    {VisemeFormat::rhubarb_json, "rhubarb-json"},
}};

std::string_view to_string(VisemeFormat format);
std::optional<VisemeFormat> viseme_format_from_string(std::string_view name);
/// The vocabulary a format is written in.
VisemeVocabulary vocabulary_of(VisemeFormat format);

/// One Rhubarb mouth cue: `shape` from `start_cs` to the next cue's start (or the end).
struct RhubarbCue {
  std::int64_t start_cs = 0;  ///< centiseconds (Rhubarb's time unit)
  std::string_view shape;     ///< "A" … "H", "X"
  bool operator==(const RhubarbCue&) const = default;
};

/// The frame rate the rhubarb formats are rendered at when the caller names none: Rhubarb's own
/// cue resolution (10 ms). At the tracks' usual 30 fps a 40 ms vowel between consonants often shows
/// its open shape only on the frame after its middle (docs/output-formats.md, `rhubarb-tsv`).
inline constexpr int kRhubarbCueFps = 100;

/// Rhubarb's cues from viseme events (of a rhubarb classifier): each event's start rounded to the
/// nearest centisecond (half up); when two events round to the same centisecond the later one wins;
/// equal neighbours merge; cues at or after the end (`end_us` truncated to a centisecond, as Rhubarb
/// truncates its duration) are dropped. The first cue starts at 0 (X, or A without X, if the events
/// begin later).
std::vector<RhubarbCue> rhubarb_cues(const VisemeClassifier& classifier, const std::vector<VisemeEvent>& events,
                                     std::int64_t end_us);

struct VisemeTrackView {
  std::string_view model;  ///< name of the model that produced the track
  const VisemeClassifier& classifier;
  const Track& track;          ///< the frames the visemes were computed from
  const VisemeTrack& visemes;  ///< compute_visemes(classifier, track)
  std::int64_t end_us = 0;     ///< end of the utterance (Rhubarb's duration)
};

/// Writes `view` in `format`. Throws std::invalid_argument when the classifier's vocabulary is not
/// the format's or the arrays disagree in size.
void write_visemes(const VisemeTrackView& view, VisemeFormat format, std::ostream& out);

}  // namespace lipsync
