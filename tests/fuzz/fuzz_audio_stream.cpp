// libFuzzer target: Listen's request reader, the audio stream (lipsync/speech/audio.hpp):
// AudioStreamReader over bytes cut into pieces at places the input chooses, as raw PCM or as a
// WAV file (the input's last two bytes choose which, and the cuts), then the streaming resampler
// over what it read.
// Contract: push and finish return or throw InputError; where the whole bytes also decode with
// decode_wav to samples and the stream ends cleanly, the samples are decode_wav's (a declared data
// size of 0 is read to the end by the stream, as nothing by decode_wav); the streaming resampler's
// samples are resample()'s of the whole.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "fuzz_support.hpp"
#include "lipsync/error.hpp"
#include "lipsync/speech/audio.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lipsync;
  if (size < 2) return 0;
  // The last two bytes choose the reading (so that a seed WAV file stays one at the front).
  const std::uint8_t mode = data[size - 1], cut = data[size - 2];
  const bool wav = (mode & 1) == 0;
  const int channels = 1 + ((mode >> 1) & 1);
  const std::size_t piece = 1 + cut % 61;  // where the pieces are cut
  const std::string_view content = fuzz::bytes(data, size - 2);
  speech::AudioStreamReader reader(
      wav ? speech::AudioStreamReader::Encoding::wav : speech::AudioStreamReader::Encoding::pcm_s16le, wav ? 0 : 16000,
      wav ? 0 : channels, "audio");
  std::vector<std::int16_t> samples;
  try {
    for (std::size_t at = 0; at < content.size(); at += piece) reader.push(content.substr(at, piece), samples);
    reader.finish();
  } catch (const InputError&) {
    return 0;
  }
  if (wav) {
    try {
      // A data size of 0 is a streaming writer's "unknown" to the stream (read to its end) and an
      // empty file to decode_wav: they agree wherever decode_wav reads samples.
      const speech::DecodedWav whole = speech::decode_wav(content, "audio");
      if (!whole.audio.samples.empty()) {
        fuzz::check(whole.audio.samples == samples, "the stream reads the samples decode_wav reads");
      }
    } catch (const InputError&) {
    }
  }
  const int rate = reader.sample_rate_hz();
  if (rate < 8000 || rate > 48000 || samples.size() > 48000) return 0;
  speech::PcmAudio audio;
  audio.sample_rate_hz = rate;
  audio.samples = samples;
  std::vector<std::int16_t> streamed;
  speech::StreamingResampler resampler(rate, 16000);
  for (std::size_t at = 0; at < samples.size(); at += piece * 7) {
    resampler.push(std::span(samples).subspan(at, std::min(piece * 7, samples.size() - at)), streamed);
  }
  resampler.finish(streamed);
  fuzz::check(streamed == speech::resample(audio, 16000).samples, "the streaming resampler gives resample()'s samples");
  return 0;
}
