// Visemes from the coarticulated channels (docs/output-formats.md, "Visemes").
//
// A viseme is a class of mouth shapes that engines key by name or id: the Oculus/MPEG-4 15, Azure's
// (SAPI's) 22 ids, Amazon Polly's 17 symbols, Rhubarb Lip Sync's mouth shapes A–H and X. The layer is
// computed from each frame's channel values, not looked up from the phoneme under the frame, so what
// the coarticulation engine did shows in the visemes: the /k/ of "coin" is already rounded, the lips
// of a closure are shut at its key frames whatever the neighbours.
//
// Method. Each viseme has a prototype in channel space: the mean of the model's targets of the
// phonemes it stands for (for /p b m/ the closures pcl, bcl, m: the visible shape of a bilabial is its
// hold). A frame's weight for viseme v is a softmax of the negative weighted squared distance,
//
//     d²_v = Σ_c w_c · ((x_c − P_vc) / range_c)²,      weight_v = exp(−d²_v / T) / Σ_u exp(−d²_u / T),
//
// with w_c = 1 for lips and jaw, 0.5 for the tongue (less visible), and 4 on the model's closing
// channels (those where a closure phoneme dominates every other phoneme: lips and jaw for /p b m f v/),
// so that a frame whose lips are sealed is PP / 21 / p / A however its tongue is placed. T is a
// quarter of the median, over visemes, of the squared distance from a prototype to its nearest other
// prototype: a frame on a prototype gives that viseme about e⁴ ≈ 55 times the weight of the nearest
// other one, whatever the model's scale.
//
// Known shapes. The weights say what the channels look like; the frame's viseme (its winner) also
// uses what the phonemes say (Track::articulation, filled by the renderers). Near a closure the
// channels can look like the wrong closure: at a /v/ before /ax w/ the upper lip already follows
// the rounding to come and the frame lies nearer the bilabial prototype than the labiodental one;
// in a pause the channels already anticipate the next phoneme. So:
//   - at a frame inside the hold of a /p b m f v/ closure (its key frames), the winner is the viseme
//     that stands for that closure phoneme (PP / 21 / p / A for pcl bcl m, FF / 18 / f / G for f v);
//     where two closures meet ("of my") the one of the two with the larger weight;
//   - at a frame in a pause at least kPauseSpeechReachUs from the speech on both sides (a leading or
//     trailing pause, the middle of a long one), the winner is the silence viseme;
//   - elsewhere the largest weight (the lowest index on a tie).
// The weights are left as the channels give them.
//
// Events: a new event (viseme, start_us) at every frame whose winner differs from the previous
// frame's; the first frame always starts one. VisemeEventDetector does this frame by frame, so a
// stream cut into batches gives the same events as a whole track.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/model.hpp"
#include "lipsync/track.hpp"

namespace lipsync {

enum class VisemeVocabulary {
  oculus,   ///< Oculus/Meta OVRLipSync, MPEG-4: 15, ids 0–14 (sil PP FF TH DD kk CH SS nn RR aa E ih oh ou)
  azure,    ///< Microsoft SAPI / Azure viseme ids 0–21 (names are the ids)
  polly,    ///< Amazon Polly's 17 symbols (sil p t S T f k i r s u @ a e E o O)
  rhubarb,  ///< Rhubarb Lip Sync's mouth shapes A B C D E F G H X
};

std::string_view to_string(VisemeVocabulary vocabulary);
std::optional<VisemeVocabulary> viseme_vocabulary_from_string(std::string_view name);

/// Rhubarb's optional "extended" shapes (its --extendedShapes, default GHX). A shape left out gives
/// its weight to the basic shape Rhubarb 1.x substitutes for it: G → B, H → C, X → A.
struct RhubarbShapes {
  bool g = true;  ///< G: upper teeth on the lower lip (/f v/)
  bool h = true;  ///< H: long /l/, tongue raised
  bool x = true;  ///< X: idle, lips closed and relaxed
  bool operator==(const RhubarbShapes&) const = default;
};

/// "GHX", "GX", "" (any order, each letter at most once); nullopt for anything else.
std::optional<RhubarbShapes> rhubarb_shapes_from_string(std::string_view letters);
std::string to_string(const RhubarbShapes& shapes);

struct VisemeOptions {
  VisemeVocabulary vocabulary = VisemeVocabulary::oculus;
  RhubarbShapes rhubarb_shapes = {};  ///< rhubarb only
};

/// One viseme event: `viseme` (index into VisemeClassifier::names(), which for Oculus and Azure is
/// the vendor's id) holds from `start_us` until the next event.
struct VisemeEvent {
  std::uint32_t viseme = 0;
  std::int64_t start_us = 0;  ///< utterance time, microseconds (a frame time)
  bool operator==(const VisemeEvent&) const = default;
};

class VisemeClassifier {
 public:
  /// Builds the prototypes from `model`'s phoneme targets. Throws InputError naming the model, the
  /// vocabulary and the viseme when the model has none of the phonemes a viseme stands for.
  VisemeClassifier(const ArticulationModel& model, const VisemeOptions& options = {});

  const VisemeOptions& options() const { return options_; }
  std::size_t channel_count() const { return channel_count_; }
  std::size_t viseme_count() const { return names_.size(); }
  /// Viseme names in index order ("sil", "PP", …; Azure "0" … "21"; Rhubarb "A" … "H", "X").
  const std::vector<std::string>& names() const { return names_; }
  /// Index of the silence viseme (Rhubarb: X, or A when X is left out).
  std::uint32_t silence() const { return silence_; }
  /// The prototype of viseme `v`: one value per channel.
  std::span<const double> prototype(std::size_t v) const {
    return {prototypes_.data() + v * channel_count_, channel_count_};
  }
  /// The softmax temperature T (in weighted, range-normalised squared channel units).
  double temperature() const { return temperature_; }

  /// Writes the viseme weights of one frame (each in [0, 1], summing to 1; a Rhubarb shape left out
  /// weighs 0) into `weights` (viseme_count()). No allocation.
  void weigh(std::span<const float> channel_values, std::span<float> weights) const;

  /// The index of the largest weight (the lowest index on a tie).
  static std::uint32_t winner(std::span<const float> weights);
  /// The frame's viseme: the winner given what the phonemes say about it ("Known shapes" above).
  std::uint32_t winner(std::span<const float> weights, const FrameArticulation& articulation) const;

  /// A pause frame this far (µs) from speech on both sides shows the silence viseme.
  static constexpr std::int64_t kPauseSpeechReachUs = 60'000;

 private:
  VisemeOptions options_;
  std::size_t channel_count_ = 0;
  std::vector<std::string> names_;
  std::uint32_t silence_ = 0;
  std::vector<double> prototypes_;            // viseme × channel
  std::vector<double> channel_scale_;         // w_c / range_c²
  std::vector<std::uint32_t> fold_into_;      // viseme whose weight this one's goes to (itself if kept)
  std::vector<std::int32_t> closure_viseme_;  // per model phoneme: the viseme a closure phoneme stands for, or −1
  double temperature_ = 1.0;
};

/// Turns a sequence of frame winners into events, one frame at a time.
class VisemeEventDetector {
 public:
  /// The event frame (`t_us`, `winner`) starts, if its winner differs from the previous frame's.
  std::optional<VisemeEvent> next(std::int64_t t_us, std::uint32_t winner);

 private:
  std::optional<std::uint32_t> current_;
};

/// The visemes of a whole track.
struct VisemeTrack {
  std::size_t viseme_count = 0;
  std::vector<float> weights;          ///< frame-major, frame_count × viseme_count
  std::vector<std::uint32_t> winners;  ///< one per frame
  std::vector<VisemeEvent> events;
};

/// Weighs every frame of `track` (which must have the classifier's channel count; else
/// std::invalid_argument), chooses each frame's viseme with its articulation and derives the events.
VisemeTrack compute_visemes(const VisemeClassifier& classifier, const Track& track);

}  // namespace lipsync
