// MFCC features with deltas and per-utterance normalisation
// (lipsync/speech/acoustic_features.hpp).
#include "lipsync/speech/acoustic_features.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>

namespace lipsync::speech {
namespace {

constexpr std::size_t kWindowSamples = kFeatureRateHz * kFeatureWindowUs / 1'000'000;  // 400
constexpr std::size_t kHopSamples = kFeatureRateHz * kFeatureHopUs / 1'000'000;        // 160
constexpr std::size_t kFftSize = 512;
constexpr int kMelBands = 26;
constexpr int kCepstra = 13;
constexpr double kLowestHz = 100.0;
constexpr double kHighestHz = 7600.0;
constexpr double kPreEmphasis = 0.97;
constexpr int kDeltaSpan = 2;
// Weights on the mean-normalised features (variances are kept: normalising them made a
// pause's frames look like every other's). The deltas, the spectrum's movement, mark phone
// boundaries best across voices, the level c0 least; chosen on the Festival corpus of
// tools/speech/measure_language_alignment.py (docs/languages.md).
constexpr double kLevelWeight = 0.6;
constexpr double kDeltaWeight = 3.0;
// Floor of a band's power (relative to full scale squared), so digital silence has a finite log.
constexpr double kPowerFloor = 1e-10;
// How far below the utterance's loudest band power every band is floored, dB.
constexpr double kFloorBelowLoudestDb = 60.0;

double hz_to_mel(double hz) { return 2595.0 * std::log10(1.0 + hz / 700.0); }
double mel_to_hz(double mel) { return 700.0 * (std::pow(10.0, mel / 2595.0) - 1.0); }

// In-place iterative radix-2 FFT of size kFftSize.
void fft(std::vector<std::complex<double>>& data) {
  const std::size_t n = data.size();
  for (std::size_t i = 1, j = 0; i < n; ++i) {
    std::size_t bit = n >> 1;
    for (; j & bit; bit >>= 1) j ^= bit;
    j ^= bit;
    if (i < j) std::swap(data[i], data[j]);
  }
  for (std::size_t length = 2; length <= n; length <<= 1) {
    const double angle = -2.0 * std::numbers::pi / static_cast<double>(length);
    const std::complex<double> step(std::cos(angle), std::sin(angle));
    for (std::size_t start = 0; start < n; start += length) {
      std::complex<double> twiddle(1.0, 0.0);
      for (std::size_t k = 0; k < length / 2; ++k) {
        const std::complex<double> even = data[start + k];
        const std::complex<double> odd = data[start + k + length / 2] * twiddle;
        data[start + k] = even + odd;
        data[start + k + length / 2] = even - odd;
        twiddle *= step;
      }
    }
  }
}

// Triangular mel filters: for each band, its weight on each FFT bin 0 … kFftSize/2.
std::vector<std::vector<double>> mel_filterbank() {
  const std::size_t bins = kFftSize / 2 + 1;
  std::vector<double> edges_hz(kMelBands + 2);
  const double low = hz_to_mel(kLowestHz), high = hz_to_mel(kHighestHz);
  for (int i = 0; i < kMelBands + 2; ++i) edges_hz[i] = mel_to_hz(low + (high - low) * i / (kMelBands + 1));
  std::vector<std::vector<double>> filters(kMelBands, std::vector<double>(bins, 0.0));
  for (int band = 0; band < kMelBands; ++band) {
    for (std::size_t bin = 0; bin < bins; ++bin) {
      const double hz = static_cast<double>(bin) * kFeatureRateHz / kFftSize;
      const double rise = (hz - edges_hz[band]) / (edges_hz[band + 1] - edges_hz[band]);
      const double fall = (edges_hz[band + 2] - hz) / (edges_hz[band + 2] - edges_hz[band + 1]);
      filters[band][bin] = std::max(0.0, std::min(rise, fall));
    }
  }
  return filters;
}

}  // namespace

FeatureFrames mfcc_features(const PcmAudio& audio) { return mfcc_features(audio, FeatureNormalisation{}); }

FeatureFrames mfcc_features(const PcmAudio& audio, const FeatureNormalisation& normalisation,
                            FeatureStatistics* statistics) {
  FeatureFrames result;
  result.dimensions = 2 * kCepstra;
  const std::vector<std::int16_t>& samples = audio.samples;
  if (samples.size() < kWindowSamples) return result;
  const std::size_t frames = 1 + (samples.size() - kWindowSamples) / kHopSamples;

  std::vector<double> window(kWindowSamples);
  for (std::size_t i = 0; i < kWindowSamples; ++i)
    window[i] = 0.54 - 0.46 * std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / (kWindowSamples - 1));
  const std::vector<std::vector<double>> filters = mel_filterbank();
  // DCT-II basis: cepstrum c = Σ_band log(power_band) · cos(π c (band + ½) / bands).
  std::vector<double> dct(kCepstra * kMelBands);
  for (int c = 0; c < kCepstra; ++c)
    for (int band = 0; band < kMelBands; ++band)
      dct[c * kMelBands + band] = std::cos(std::numbers::pi * c * (band + 0.5) / kMelBands);

  std::vector<double> cepstra(frames * kCepstra);
  result.level_db.resize(frames);
  std::vector<std::complex<double>> spectrum(kFftSize);
  std::vector<double> power(kFftSize / 2 + 1), log_bands(kMelBands), band_power(frames * kMelBands);
  for (std::size_t k = 0; k < frames; ++k) {
    const std::int16_t* x = samples.data() + k * kHopSamples;
    double energy = 0.0;
    for (std::size_t i = 0; i < kWindowSamples; ++i) {
      const double sample = x[i] / 32768.0;
      energy += sample * sample;
      const double previous = (i == 0 ? (k * kHopSamples == 0 ? 0.0 : x[-1] / 32768.0) : x[i - 1] / 32768.0);
      spectrum[i] = (sample - kPreEmphasis * previous) * window[i];
    }
    std::fill(spectrum.begin() + kWindowSamples, spectrum.end(), 0.0);
    result.level_db[k] = 10.0 * std::log10(std::max(energy / kWindowSamples, 1e-20));
    fft(spectrum);
    for (std::size_t bin = 0; bin < power.size(); ++bin) power[bin] = std::norm(spectrum[bin]);
    for (int band = 0; band < kMelBands; ++band) {
      double sum = 0.0;
      for (std::size_t bin = 0; bin < power.size(); ++bin) sum += filters[band][bin] * power[bin];
      band_power[k * kMelBands + band] = sum;
    }
  }
  // Every band floored at kFloorBelowLoudestDb under the loudest band power of the utterance:
  // digital silence and a quiet room's noise then look alike.
  const double own_loudest = *std::max_element(band_power.begin(), band_power.end());
  const double loudest =
      std::max(kPowerFloor, normalisation.loudest_band_power > 0 ? normalisation.loudest_band_power : own_loudest);
  const double floor = loudest * std::pow(10.0, -kFloorBelowLoudestDb / 10.0);
  for (std::size_t k = 0; k < frames; ++k) {
    for (int band = 0; band < kMelBands; ++band)
      log_bands[band] = std::log(std::max(band_power[k * kMelBands + band], floor));
    for (int c = 0; c < kCepstra; ++c) {
      double sum = 0.0;
      for (int band = 0; band < kMelBands; ++band) sum += dct[c * kMelBands + band] * log_bands[band];
      cepstra[k * kCepstra + c] = sum;
    }
  }

  // Deltas: d_k = Σ_n n (c_{k+n} − c_{k−n}) / (2 Σ_n n²), frames clamped at the ends.
  const int dims = result.dimensions;
  std::vector<double> features(frames * dims);
  const double denominator = 2.0 * (1 * 1 + 2 * 2);
  for (std::size_t k = 0; k < frames; ++k) {
    for (int c = 0; c < kCepstra; ++c) {
      features[k * dims + c] = cepstra[k * kCepstra + c];
      double delta = 0.0;
      for (int n = 1; n <= kDeltaSpan; ++n) {
        const std::size_t after = std::min(frames - 1, k + n);
        const std::size_t before = k >= static_cast<std::size_t>(n) ? k - n : 0;
        delta += n * (cepstra[after * kCepstra + c] - cepstra[before * kCepstra + c]);
      }
      features[k * dims + kCepstra + c] = delta / denominator;
    }
  }
  // Cepstral mean normalisation over the utterance (or by the stream's means), then the weights.
  const bool own_means = normalisation.means.size() != static_cast<std::size_t>(dims);
  result.values.resize(frames * dims);
  for (int d = 0; d < dims; ++d) {
    double mean = 0.0;
    if (own_means) {
      for (std::size_t k = 0; k < frames; ++k) mean += features[k * dims + d];
      mean /= static_cast<double>(frames);
    } else {
      mean = normalisation.means[static_cast<std::size_t>(d)];
    }
    const double weight = d == 0 ? kLevelWeight : d >= kCepstra ? kDeltaWeight : 1.0;
    for (std::size_t k = 0; k < frames; ++k)
      result.values[k * dims + d] = static_cast<float>((features[k * dims + d] - mean) * weight);
  }
  if (statistics != nullptr) {
    statistics->loudest_band_power = own_loudest;
    statistics->unweighted = std::move(features);
  }
  return result;
}

}  // namespace lipsync::speech
