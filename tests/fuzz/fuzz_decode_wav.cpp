// libFuzzer target: the WAV reader of the audio input (lipsync/speech/audio.hpp),
// then what the aligner does with its result before decoding: the resampler to
// 16 kHz and the closure refiner over lip phones tiling the audio.
// Contract: decode_wav and wav_layout_and_duration_us return or throw InputError;
// decoded audio has a positive rate; resampled audio has the length its rate
// implies; refined phones still tile the audio, in order, each non-empty.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <iterator>

#include "fuzz_support.hpp"
#include "lipsync/error.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/closure_refiner.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lipsync;
  const std::string_view content = fuzz::bytes(data, size);
  try {
    (void)speech::wav_layout_and_duration_us(content, "input.wav");
  } catch (const InputError&) {
  }
  speech::DecodedWav decoded;
  try {
    decoded = speech::decode_wav(content, "input.wav");
  } catch (const InputError&) {
    return 0;
  }
  fuzz::check(decoded.audio.sample_rate_hz > 0, "decoded audio has a positive sample rate");
  // The aligner refuses rates under 8 kHz and audio over 120 s before resampling.
  if (decoded.audio.sample_rate_hz < 8000 || decoded.audio.sample_rate_hz > 384000) return 0;
  const speech::PcmAudio audio = speech::resample(decoded.audio, 16000);
  const double expected = double(decoded.audio.samples.size()) * 16000.0 / decoded.audio.sample_rate_hz;
  fuzz::check(std::abs(double(audio.samples.size()) - expected) <= 2.0, "resampled length matches the rate ratio");
  const std::int64_t end_us = audio.duration_us();
  if (end_us < 60'000) return 0;
  LabeledUtterance phones;
  const char* labels[] = {"", "P", "AA", "M", "IY", "F", "B", "V", ""};
  const std::int64_t n = std::size(labels);
  for (std::int64_t i = 0; i < n; ++i) {
    phones.intervals.push_back({labels[i], end_us * i / n, end_us * (i + 1) / n, int(i) + 1});
  }
  (void)speech::refine_closures(audio, phones);
  fuzz::check(phones.intervals.front().start_us == 0 && phones.intervals.back().end_us == end_us,
              "refined phones span the same audio");
  for (std::size_t i = 0; i < phones.intervals.size(); ++i) {
    fuzz::check(phones.intervals[i].start_us < phones.intervals[i].end_us, "refined phones are non-empty");
    if (i > 0) fuzz::check(phones.intervals[i].start_us == phones.intervals[i - 1].end_us, "refined phones tile");
  }
  return 0;
}
