// Visemes from channel values (method and reasoning: visemes.hpp, docs/output-formats.md).
//
// The tables below say which of the model's phonemes each viseme stands for; they only feed the
// prototypes (the mean of those phonemes' targets), never a per-frame lookup. Phoneme names are the
// default model's ARPAbet-like inventory; a name the model lacks is skipped, a viseme left with no
// phoneme at all is an error.
#include "lipsync/visemes.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <stdexcept>

#include "lipsync/error.hpp"

namespace lipsync {
namespace {

struct VisemeRow {
  std::string_view name;
  std::initializer_list<std::string_view> phonemes;
};

// Oculus/MPEG-4: index = OVRLipSync's viseme id.
const VisemeRow kOculus[] = {
    {"sil", {"sil"}},
    {"PP", {"pcl", "bcl", "m"}},  // the hold of /p b m/: what is seen of a bilabial
    {"FF", {"f", "v"}},
    {"TH", {"th", "dh"}},
    {"DD", {"t", "d", "dx"}},
    {"kk", {"k", "g", "ng"}},
    {"CH", {"ch", "jh", "sh", "zh"}},
    {"SS", {"s", "z"}},
    {"nn", {"n", "l"}},
    {"RR", {"r", "er"}},  // r-coloured vowel with /r/, as OVRLipSync's examples do
    {"aa", {"aa", "ae", "ah", "ay", "aw"}},
    {"E", {"eh", "ey", "ax"}},
    {"ih", {"ih", "iy", "y"}},
    {"oh", {"ao", "ow", "oy"}},
    {"ou", {"uw", "uh", "w"}},
};

// Azure / SAPI: index = VisemeId (SPVISEMES). 'ix' is not in the default model.
const VisemeRow kAzure[] = {
    {"0", {"sil"}},
    {"1", {"ae", "ax", "ah"}},
    {"2", {"aa"}},
    {"3", {"ao"}},
    {"4", {"ey", "eh", "uh"}},
    {"5", {"er"}},
    {"6", {"y", "iy", "ih", "ix"}},
    {"7", {"w", "uw"}},
    {"8", {"ow"}},
    {"9", {"aw"}},
    {"10", {"oy"}},
    {"11", {"ay"}},
    {"12", {"hh"}},
    {"13", {"r"}},
    {"14", {"l"}},
    {"15", {"s", "z"}},
    {"16", {"sh", "ch", "jh", "zh"}},
    {"17", {"th", "dh"}},
    {"18", {"f", "v"}},
    {"19", {"d", "t", "n", "dx"}},
    {"20", {"k", "g", "ng"}},
    {"21", {"pcl", "bcl", "m"}},
};

// Amazon Polly, after its en-US phoneme/viseme table (/h/ is k, /l/ and /n/ are t, /j/ is i, /w/ is u).
const VisemeRow kPolly[] = {
    {"sil", {"sil"}},
    {"p", {"pcl", "bcl", "m"}},
    {"t", {"t", "d", "n", "l", "dx"}},
    {"S", {"sh", "zh", "ch", "jh"}},
    {"T", {"th", "dh"}},
    {"f", {"f", "v"}},
    {"k", {"k", "g", "ng", "hh"}},
    {"i", {"iy", "ih", "y"}},
    {"r", {"r"}},
    {"s", {"s", "z"}},
    {"u", {"uw", "uh", "w"}},
    {"@", {"ax"}},
    {"a", {"aa", "ae", "ay", "aw"}},
    {"e", {"eh", "ey"}},
    {"E", {"ah", "er"}},
    {"o", {"ow"}},
    {"O", {"ao", "oy"}},
};

// Rhubarb Lip Sync's shapes, in its order, after its README's descriptions.
const VisemeRow kRhubarb[] = {
    {"A", {"pcl", "bcl", "m"}},  // closed, slight pressure
    {"B",
     {"t", "d", "k", "g", "ng", "s", "z", "sh", "zh", "ch", "jh", "th", "dh", "n", "y", "iy", "ih", "dx",
      "hh"}},                               // clenched teeth: most consonants, EE
    {"C", {"eh", "ae", "ah", "ax", "ey"}},  // open: men, bat
    {"D", {"aa", "ay", "aw"}},              // wide open: father
    {"E", {"ao", "er", "r"}},               // slightly rounded: off, bird
    {"F", {"uw", "ow", "w", "uh", "oy"}},   // puckered: you, show, way
    {"G", {"f", "v"}},                      // upper teeth on the lower lip
    {"H", {"l"}},                           // long L, tongue raised
    {"X", {"sil"}},                         // idle
};
// The largest vocabulary (Azure) has 22.
constexpr std::size_t kMaxVisemes = 22;
constexpr std::uint32_t kRhubarbA = 0, kRhubarbB = 1, kRhubarbC = 2, kRhubarbG = 6, kRhubarbH = 7, kRhubarbX = 8;

std::span<const VisemeRow> rows(VisemeVocabulary vocabulary) {
  switch (vocabulary) {
    case VisemeVocabulary::oculus:
      return kOculus;
    case VisemeVocabulary::azure:
      return kAzure;
    case VisemeVocabulary::polly:
      return kPolly;
    case VisemeVocabulary::rhubarb:
      return kRhubarb;
  }
  return {};
}

// Channel weights w_c before range normalisation.
constexpr double kVisibleWeight = 1.0;  // lips, cheeks, jaw
constexpr double kTongueWeight = 0.5;   // seen only through the open mouth
constexpr double kClosingWeight = 4.0;  // channels a closure phoneme dominates
constexpr double kClosingAlphaRatio = 10.0;
constexpr double kShapingWeight = 2.0;  // channels a closure shapes without sealing (the raised upper lip of /f v/)
constexpr double kShapingAlphaRatio = 2.0;
// T = kTemperatureShare × median over visemes of the squared distance to the nearest other prototype.
constexpr double kTemperatureShare = 0.25;

}  // namespace

std::string_view to_string(VisemeVocabulary vocabulary) {
  switch (vocabulary) {
    case VisemeVocabulary::oculus:
      return "oculus";
    case VisemeVocabulary::azure:
      return "azure";
    case VisemeVocabulary::polly:
      return "polly";
    case VisemeVocabulary::rhubarb:
      return "rhubarb";
  }
  return "?";
}

std::optional<VisemeVocabulary> viseme_vocabulary_from_string(std::string_view name) {
  for (auto vocabulary :
       {VisemeVocabulary::oculus, VisemeVocabulary::azure, VisemeVocabulary::polly, VisemeVocabulary::rhubarb}) {
    if (to_string(vocabulary) == name) return vocabulary;
  }
  return std::nullopt;
}

std::optional<RhubarbShapes> rhubarb_shapes_from_string(std::string_view letters) {
  RhubarbShapes shapes{false, false, false};
  for (const char letter : letters) {
    bool* flag = letter == 'G' ? &shapes.g : letter == 'H' ? &shapes.h : letter == 'X' ? &shapes.x : nullptr;
    if (!flag || *flag) return std::nullopt;
    *flag = true;
  }
  return shapes;
}

std::string to_string(const RhubarbShapes& shapes) {
  std::string letters;
  if (shapes.g) letters += 'G';
  if (shapes.h) letters += 'H';
  if (shapes.x) letters += 'X';
  return letters;
}

VisemeClassifier::VisemeClassifier(const ArticulationModel& model, const VisemeOptions& options)
    : options_(options), channel_count_(model.channel_count()) {
  const auto table = rows(options.vocabulary);
  const std::size_t count = table.size();
  if (count > kMaxVisemes) throw std::logic_error("viseme table larger than kMaxVisemes");
  names_.reserve(count);
  prototypes_.assign(count * channel_count_, 0.0);
  for (std::size_t v = 0; v < count; ++v) {
    names_.emplace_back(table[v].name);
    std::size_t found = 0;
    for (const std::string_view phoneme : table[v].phonemes) {
      const auto index = model.find_phoneme(phoneme);
      if (!index) continue;
      const PhonemeSpec& spec = model.phoneme(*index);
      for (std::size_t c = 0; c < channel_count_; ++c) prototypes_[v * channel_count_ + c] += spec.targets[c];
      ++found;
    }
    if (found == 0) {
      std::string wanted;
      for (const std::string_view phoneme : table[v].phonemes)
        wanted += (wanted.empty() ? "" : " ") + std::string(phoneme);
      throw InputError("model '" + model.name() + "'", 0,
                       std::string(to_string(options.vocabulary)) + " viseme '" + names_.back() +
                           "': the model has none of its phonemes (" + wanted + ")");
    }
    for (std::size_t c = 0; c < channel_count_; ++c) prototypes_[v * channel_count_ + c] /= static_cast<double>(found);
  }

  // Channel weights: a channel is closing when some closure phoneme's α on it is at least
  // kClosingAlphaRatio times every other phoneme's (the default model: α = 100 against ≤ 5 on lips
  // and jaw for /p b m f v/; /f v/ also raise the upper lip with α = 6 against 1, which is not a
  // closure: weighting it would pull the shared key frame of "of my" toward FF).
  channel_scale_.resize(channel_count_);
  for (std::size_t c = 0; c < channel_count_; ++c) {
    double closure_alpha = 0.0, other_alpha = 0.0;
    for (const PhonemeSpec& spec : model.phonemes()) {
      double& slot = spec.phoneme_class == PhonemeClass::closure ? closure_alpha : other_alpha;
      slot = std::max(slot, spec.dominance[c].alpha);
    }
    const ChannelSpec& channel = model.channels()[c];
    double weight = channel.kind == "tongue" ? kTongueWeight : kVisibleWeight;
    if (closure_alpha >= kClosingAlphaRatio * other_alpha) {
      weight = kClosingWeight;
    } else if (closure_alpha >= kShapingAlphaRatio * other_alpha) {
      weight = kShapingWeight;
    }
    const double range = channel.max - channel.min;
    channel_scale_[c] = range > 0 ? weight / (range * range) : 0.0;
  }

  fold_into_.resize(count);
  for (std::uint32_t v = 0; v < count; ++v) fold_into_[v] = v;
  silence_ = 0;
  if (options.vocabulary == VisemeVocabulary::rhubarb) {
    if (!options.rhubarb_shapes.g) fold_into_[kRhubarbG] = kRhubarbB;
    if (!options.rhubarb_shapes.h) fold_into_[kRhubarbH] = kRhubarbC;
    if (!options.rhubarb_shapes.x) fold_into_[kRhubarbX] = kRhubarbA;
    silence_ = fold_into_[kRhubarbX];
  }
  // The viseme each closure phoneme stands for (the row that lists it), for the frames it holds.
  closure_viseme_.assign(model.phonemes().size(), -1);
  for (std::uint32_t v = 0; v < count; ++v) {
    for (const std::string_view phoneme : table[v].phonemes) {
      const auto index = model.find_phoneme(phoneme);
      if (index && model.phoneme(*index).phoneme_class == PhonemeClass::closure) {
        closure_viseme_[*index] = static_cast<std::int32_t>(fold_into_[v]);
      }
    }
  }

  // Temperature from the prototypes' spacing (all shapes, whichever are kept).
  std::vector<double> nearest;
  for (std::size_t v = 0; v < count; ++v) {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t u = 0; u < count; ++u) {
      if (u == v) continue;
      double d2 = 0.0;
      for (std::size_t c = 0; c < channel_count_; ++c) {
        const double diff = prototypes_[v * channel_count_ + c] - prototypes_[u * channel_count_ + c];
        d2 += channel_scale_[c] * diff * diff;
      }
      best = std::min(best, d2);
    }
    if (std::isfinite(best) && best > 0) nearest.push_back(best);
  }
  if (!nearest.empty()) {
    std::nth_element(nearest.begin(), nearest.begin() + static_cast<std::ptrdiff_t>(nearest.size() / 2), nearest.end());
    temperature_ = kTemperatureShare * nearest[nearest.size() / 2];
  }
}

void VisemeClassifier::weigh(std::span<const float> channel_values, std::span<float> weights) const {
  const std::size_t count = names_.size();
  std::array<double, kMaxVisemes> scores{};  // −d²/T per viseme
  double best = -std::numeric_limits<double>::infinity();
  for (std::size_t v = 0; v < count; ++v) {
    double d2 = 0.0;
    const double* p = prototypes_.data() + v * channel_count_;
    for (std::size_t c = 0; c < channel_count_; ++c) {
      const double diff = static_cast<double>(channel_values[c]) - p[c];
      d2 += channel_scale_[c] * diff * diff;
    }
    scores[v] = -d2 / temperature_;
    best = std::max(best, scores[v]);
  }
  // The best term is exp(0) = 1, so the sum is >= 1: no 0/0 however far the frame is. A Rhubarb
  // shape left out adds its term to its substitute's, so the kept shapes' weights are the sums of
  // the full set's.
  std::array<double, kMaxVisemes> folded{};
  double sum = 0.0;
  for (std::size_t v = 0; v < count; ++v) {
    const double term = std::exp(scores[v] - best);
    folded[fold_into_[v]] += term;
    sum += term;
  }
  for (std::size_t v = 0; v < count; ++v) weights[v] = static_cast<float>(folded[v] / sum);
}

std::uint32_t VisemeClassifier::winner(std::span<const float> weights) {
  std::uint32_t best = 0;
  for (std::uint32_t v = 1; v < weights.size(); ++v) {
    if (weights[v] > weights[best]) best = v;
  }
  return best;
}

std::uint32_t VisemeClassifier::winner(std::span<const float> weights, const FrameArticulation& articulation) const {
  const auto closure_viseme = [this](std::int32_t phoneme) {
    return phoneme >= 0 && static_cast<std::size_t>(phoneme) < closure_viseme_.size()
               ? closure_viseme_[static_cast<std::size_t>(phoneme)]
               : -1;
  };
  const std::int32_t held = closure_viseme(articulation.closure);
  const std::int32_t meeting = closure_viseme(articulation.meeting_closure);
  if (held >= 0 || meeting >= 0) {
    if (held < 0) return static_cast<std::uint32_t>(meeting);
    if (meeting < 0) return static_cast<std::uint32_t>(held);
    const float held_weight = weights[static_cast<std::size_t>(held)];
    const float meeting_weight = weights[static_cast<std::size_t>(meeting)];
    const bool held_wins = held_weight > meeting_weight || (held_weight == meeting_weight && held < meeting);
    return static_cast<std::uint32_t>(held_wins ? held : meeting);
  }
  if (articulation.pause_us >= kPauseSpeechReachUs) return silence_;
  return winner(weights);
}

std::optional<VisemeEvent> VisemeEventDetector::next(std::int64_t t_us, std::uint32_t winner) {
  if (current_ && *current_ == winner) return std::nullopt;
  current_ = winner;
  return VisemeEvent{winner, t_us};
}

VisemeTrack compute_visemes(const VisemeClassifier& classifier, const Track& track) {
  if (track.channel_count != classifier.channel_count()) {
    throw std::invalid_argument("track has " + std::to_string(track.channel_count) +
                                " channels but the viseme classifier's model has " +
                                std::to_string(classifier.channel_count()));
  }
  VisemeTrack out;
  out.viseme_count = classifier.viseme_count();
  out.weights.resize(track.frame_count() * out.viseme_count);
  out.winners.resize(track.frame_count());
  VisemeEventDetector detector;
  for (std::size_t f = 0; f < track.frame_count(); ++f) {
    const std::span<float> weights(out.weights.data() + f * out.viseme_count, out.viseme_count);
    classifier.weigh(track.frame_values(f), weights);
    out.winners[f] = classifier.winner(weights, track.frame_articulation(f));
    if (const auto event = detector.next(track.t_us[f], out.winners[f])) out.events.push_back(*event);
  }
  return out;
}

}  // namespace lipsync
