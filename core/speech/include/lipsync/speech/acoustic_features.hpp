// Acoustic features for comparing two renderings of the same words: mel-frequency
// cepstral coefficients (MFCC) every 10 ms, with their deltas, normalised per
// utterance.
//
// Each frame analyses 25 ms of 16 kHz audio (pre-emphasis 0.97, Hamming window,
// 512-point FFT), pools the power spectrum in 26 triangular mel bands between
// 100 and 7600 Hz, and takes the DCT-II of the bands' log power: c0 … c12. The
// deltas are the usual regression over ±2 frames. Every band is floored 60 dB
// under the utterance's loudest, so digital silence and a quiet room look alike.
// Cepstral mean normalisation (every dimension to mean 0 over the utterance)
// removes what a microphone, a room or a synthesiser's voice adds to every frame
// alike (a fixed filter is a constant offset of the cepstrum), so a recording and
// espeak-ng's rendering of the same transcript can be compared frame by frame.
// Frame k covers [k·10 ms, k·10 ms + 25 ms]; its centre is k·10 ms + 12.5 ms.
// Pure computation: plain loops, no allocation per frame beyond the output.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "lipsync/speech/audio.hpp"

namespace lipsync::speech {

/// The analysis every feature frame uses (16 kHz audio).
inline constexpr int kFeatureRateHz = 16000;
inline constexpr std::int64_t kFeatureHopUs = 10'000;
inline constexpr std::int64_t kFeatureWindowUs = 25'000;

/// Feature vectors, one per 10 ms frame, stored row by row.
struct FeatureFrames {
  int dimensions = 0;
  std::vector<float> values;     ///< frame k's vector is values[k·dimensions, (k+1)·dimensions)
  std::vector<double> level_db;  ///< each frame's level (mean power of its window), dBFS

  std::size_t size() const { return dimensions == 0 ? 0 : values.size() / static_cast<std::size_t>(dimensions); }
  const float* frame(std::size_t k) const { return values.data() + k * static_cast<std::size_t>(dimensions); }
};

/// 13 MFCCs and their 13 deltas per frame (26 dimensions) of `audio`, which must be
/// at kFeatureRateHz (resample() first); every dimension normalised to mean 0 over
/// the frames, then c0 weighted 0.6 and the deltas 3 (for distances between frames). Audio shorter than one window
/// gives no frames.
FeatureFrames mfcc_features(const PcmAudio& audio);

/// What a stretch of a longer stream is normalised by, when the stream is heard a piece at a time
/// (a live voice): the loudest band power and the features' means of the stream so far, not of the
/// stretch alone.
struct FeatureNormalisation {
  double loudest_band_power = 0;  ///< every band is floored 60 dB under it
  std::vector<double> means;      ///< one per dimension, before the weights
};

/// What mfcc_features saw of a stretch, for a caller that keeps a stream's FeatureNormalisation.
struct FeatureStatistics {
  double loudest_band_power = 0;   ///< the stretch's own loudest band power
  std::vector<double> unweighted;  ///< each frame's features before the means and weights, row by row
};

/// mfcc_features of a stretch normalised by `normalisation` (an empty `means`, or a loudest of 0:
/// the stretch's own, as mfcc_features does); `statistics`, when given, gets what it saw.
FeatureFrames mfcc_features(const PcmAudio& audio, const FeatureNormalisation& normalisation,
                            FeatureStatistics* statistics = nullptr);

/// The Euclidean distance between frame `i` of `a` and frame `j` of `b` (the warps' frame cost).
inline double frame_distance(const FeatureFrames& a, std::size_t i, const FeatureFrames& b, std::size_t j) {
  const float* x = a.frame(i);
  const float* y = b.frame(j);
  double sum = 0.0;
  for (int d = 0; d < a.dimensions; ++d) {
    const double difference = x[d] - y[d];
    sum += difference * difference;
  }
  return std::sqrt(sum);
}

/// The centre of frame `k`, µs.
constexpr std::int64_t feature_frame_centre_us(std::size_t k) {
  return static_cast<std::int64_t>(k) * kFeatureHopUs + kFeatureWindowUs / 2;
}

}  // namespace lipsync::speech
