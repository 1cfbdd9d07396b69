// The articulation model: what each phoneme does to each articulator.
//
// Channels are the articulators of a Kähler-style face: muscle contractions
// (normalised 0..1), jaw rotation and tongue pose. Each phoneme of the model's
// inventory has, per channel, a target value and the parameters of its
// Cohen–Massaro dominance function (Eq. 2 and 3 of Albrecht, Haber & Seidel
// 2002): magnitude α, rates θ− / θ+, exponent c and peak offset t_off.
// The model also carries a linear retargeting from channels to the 52 ARKit
// blendshapes (with mouthClose capped at jawOpen). It is data (a JSON file, docs/model.md), validated once on load;
// after that every lookup is by integer index.
#pragma once

#include <array>
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lipsync {

enum class PhonemeClass { vowel, consonant, closure, release, silence };

std::string_view to_string(PhonemeClass phoneme_class);
std::optional<PhonemeClass> phoneme_class_from_string(std::string_view name);

/// Parameters of one dominance function D(t) = α · exp(−θ± · |τ|^c),
/// τ = (segment centre − t_off) − t  (Eq. 2 and 3).
struct DominanceParams {
  double alpha = 1.0;             ///< magnitude α, > 0
  double theta_minus_per_s = 10;  ///< decay rate after the peak (τ < 0), 1/s^c, > 0
  double theta_plus_per_s = 10;   ///< growth rate before the peak (τ ≥ 0), 1/s^c, > 0
  double c = 1.0;                 ///< exponent c, in [1, 4]
  double t_off_s = 0.0;           ///< peak offset from the segment centre, seconds
};

struct ChannelSpec {
  std::string name;         ///< e.g. "jaw_rotation"
  std::string kind;         ///< "muscle", "jaw" or "tongue"
  double min = 0.0;         ///< lowest valid value
  double max = 1.0;         ///< highest valid value
  double rest = 0.0;        ///< value at rest (silence)
  std::string description;  ///< unit and meaning, for documentation
};

struct PhonemeSpec {
  std::string name;  ///< model phoneme name, e.g. "aa", "pcl"
  PhonemeClass phoneme_class = PhonemeClass::vowel;
  std::vector<double> targets;             ///< one per channel
  std::vector<DominanceParams> dominance;  ///< one per channel
  /// For a release phoneme (/p/, /b/): the index of its closure phoneme, used to
  /// split an input segment that has no separate closure. -1 otherwise.
  int closure_phoneme = -1;
  /// Offset (s) of the peak used for a short-segment key frame: the t_off of
  /// the channel with the largest α (Section 3.3).
  double keyframe_t_off_s = 0.0;
};

/// Apple's 52 ARKit blendshape names in Apple's documentation order.
extern const std::array<std::string_view, 52> kArkitNames;

class ArticulationModel {
 public:
  /// Parses and validates a model. Throws InputError naming `source`, the
  /// phoneme and the field for every problem.
  static ArticulationModel from_json(std::string_view json_text, std::string_view source);
  /// The default model embedded in the binary (data/models/default.json).
  static const ArticulationModel& builtin();
  /// The JSON text of the default model, as embedded.
  static std::string_view builtin_json();

  const std::string& name() const { return name_; }
  std::size_t channel_count() const { return channels_.size(); }
  const std::vector<ChannelSpec>& channels() const { return channels_; }
  const std::vector<PhonemeSpec>& phonemes() const { return phonemes_; }
  const PhonemeSpec& phoneme(int index) const { return phonemes_[static_cast<std::size_t>(index)]; }
  std::optional<int> find_phoneme(std::string_view name) const;
  /// Index of the silence phoneme ("sil").
  int silence_phoneme() const { return silence_phoneme_; }

  /// ARKit weights (52, in kArkitNames order) for one frame of channel values:
  /// w_j = clamp(Σ_i M[j][i] · v_i, 0, 1), then mouthClose = min(mouthClose, jawOpen)
  /// (ARKit closes the lips against the jaw's opening, never beyond it).
  void retarget_to_arkit(std::span<const float> channel_values, std::span<float> arkit_out) const;
  /// Row-major 52 × channel_count retargeting matrix.
  const std::vector<double>& arkit_matrix() const { return arkit_matrix_; }

 private:
  std::string name_;
  std::vector<ChannelSpec> channels_;
  std::vector<PhonemeSpec> phonemes_;
  int silence_phoneme_ = -1;
  std::vector<double> arkit_matrix_;
};

}  // namespace lipsync
