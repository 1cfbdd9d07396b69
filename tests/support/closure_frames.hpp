// The frames at which the paper promises a closure (Section 3.2): every frame whose time lies in
// the hold of a /p b m/ or /f v/ closure, its two ends included. With key frames these are exactly
// the closure_start and closure_end frames (no frame falls inside a hold); with --fixed-rate, the
// grid frames inside. A frame where two closures meet belongs to both.
//
// What "closed" means for the channels: the closing channels (lips and jaw for /p b m/, lower lip
// and jaw for /f v/) are within kClosureTolerance of the channel's range (5 %) from the closure
// phoneme's targets. Shared by the channel, ARKit and face tests so that all three measure the
// same frames.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "lipsync/formats.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/track.hpp"

namespace lipsync::testing {

enum class ClosurePlace { bilabial, labiodental };

/// |value − target| allowed on a closing channel, as a share of the channel's range.
inline constexpr double kClosureTolerance = 0.05;

inline bool is_bilabial_closure(const std::string& phoneme) {
  return phoneme == "pcl" || phoneme == "bcl" || phoneme == "m";
}
inline bool is_labiodental_closure(const std::string& phoneme) { return phoneme == "f" || phoneme == "v"; }

/// The channels a closure of this place must reach: lips and jaw, or lower lip and jaw.
inline std::vector<std::size_t> closing_channels(const ArticulationModel& model, ClosurePlace place) {
  std::vector<std::string> names{"orbicularis_oris_lower", "mentalis", "jaw_rotation"};
  if (place == ClosurePlace::bilabial) names.push_back("orbicularis_oris_upper");
  std::vector<std::size_t> channels;
  for (const std::string& name : names) {
    for (std::size_t c = 0; c < model.channel_count(); ++c) {
      if (model.channels()[c].name == name) channels.push_back(c);
    }
  }
  return channels;
}

struct ClosureFrame {
  std::size_t frame = 0;    ///< index into the track
  std::size_t segment = 0;  ///< the closure segment whose hold contains the frame
  ClosurePlace place = ClosurePlace::bilabial;
  std::string phoneme;
};

/// Every (frame, closure) pair with the frame's time in the closure's [start, end].
inline std::vector<ClosureFrame> closure_frames(const ArticulationModel& model, const std::vector<Segment>& segments,
                                                const Track& track) {
  std::vector<ClosureFrame> out;
  std::size_t first_frame = 0;
  for (std::size_t s = 0; s < segments.size(); ++s) {
    const std::string& phoneme = model.phoneme(segments[s].phoneme).name;
    const bool bilabial = is_bilabial_closure(phoneme);
    if (!bilabial && !is_labiodental_closure(phoneme)) continue;
    while (first_frame < track.frame_count() && track.t_us[first_frame] < segments[s].start_us) ++first_frame;
    for (std::size_t f = first_frame; f < track.frame_count() && track.t_us[f] <= segments[s].end_us; ++f) {
      out.push_back({f, s, bilabial ? ClosurePlace::bilabial : ClosurePlace::labiodental, phoneme});
    }
  }
  return out;
}

/// The largest |value − target| / range over the closing channels of `closure` at its frame.
inline double closure_error(const ArticulationModel& model, const std::vector<Segment>& segments, const Track& track,
                            const ClosureFrame& closure, std::string* worst_channel = nullptr) {
  const PhonemeSpec& spec = model.phoneme(segments[closure.segment].phoneme);
  double worst = 0.0;
  for (const std::size_t c : closing_channels(model, closure.place)) {
    const ChannelSpec& channel = model.channels()[c];
    const double error = std::abs(track.frame_values(closure.frame)[c] - spec.targets[c]) / (channel.max - channel.min);
    if (error > worst) {
      worst = error;
      if (worst_channel) *worst_channel = channel.name;
    }
  }
  return worst;
}

struct TimedUtterance {
  std::string name;  ///< file name
  std::vector<Segment> segments;
};

/// The closure corpus in tests/data/closures (regenerate.sh there), as segments of `model`, in
/// file-name order: Festival's and flite's own timings (the "radio" phone set) and the same voices
/// force-aligned by PocketSphinx (TextGrids, "arpabet"). `folder` names another folder of
/// tests/data read the same way ("librivox": recorded speech aligned by PocketSphinx).
inline std::vector<TimedUtterance> load_closure_corpus(const std::string& data_dir, const ArticulationModel& model,
                                                       const std::string& folder = "closures") {
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(data_dir + "/" + folder)) {
    if (entry.path().extension() != ".sh") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  const PhoneSet radio = *PhoneSet::builtin("radio", model);
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  std::vector<TimedUtterance> corpus;
  for (const auto& path : files) {
    std::ifstream file(path, std::ios::binary);
    std::stringstream text;
    text << file.rdbuf();
    const std::string name = path.filename().string();
    const InputFormat format = detect_input_format(name, text.str());
    const PhoneSet& phone_set = format == InputFormat::textgrid ? arpabet : radio;
    corpus.push_back({name, build_segments(parse_utterance(text.str(), format, name), model, phone_set)});
  }
  return corpus;
}

}  // namespace lipsync::testing
