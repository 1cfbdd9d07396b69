// espeak-ng synthesis with phoneme events (lipsync/speech/synthesizer.hpp).
#include "lipsync/speech/synthesizer.hpp"

#include <espeak-ng/speak_lib.h>

#include <algorithm>
#include <cstring>
#include <mutex>
#include <vector>

#include "lipsync/error.hpp"

namespace lipsync::speech {
namespace {

constexpr std::string_view kSource = "espeak-ng";

// espeak-ng's globals: one initialisation per process, one synthesis at a time.
std::mutex espeak_mutex;
int espeak_rate_hz = 0;  // guarded by espeak_mutex; 0 until initialised

struct PhonemeStart {
  std::string name;
  std::int64_t sample;
};

// What the callback collects during one espeak_Synth call.
struct Collector {
  std::vector<std::int16_t> samples;
  std::vector<PhonemeStart> phonemes;
};
Collector* active_collector = nullptr;  // guarded by espeak_mutex; set during espeak_Synth

int collect(short* wav, int sample_count, espeak_EVENT* events) {
  Collector* collector = active_collector;
  if (collector == nullptr) return 0;
  if (wav != nullptr && sample_count > 0) collector->samples.insert(collector->samples.end(), wav, wav + sample_count);
  for (espeak_EVENT* event = events; event->type != espeakEVENT_LIST_TERMINATED; ++event) {
    if (event->type == espeakEVENT_PHONEME) {
      // `sample` is the event's position in the output, in samples (espeak-ng's
      // MarkerEvent); `audio_position` is the same in whole milliseconds.
      const std::string name(event->id.string, strnlen(event->id.string, sizeof event->id.string));
      collector->phonemes.push_back({name, event->sample});
    }
  }
  return 0;  // continue synthesis
}

void initialise_once() {
  if (espeak_rate_hz > 0) return;
  const int rate = espeak_Initialize(AUDIO_OUTPUT_SYNCHRONOUS, 0, nullptr,
                                     espeakINITIALIZE_PHONEME_EVENTS | espeakINITIALIZE_DONT_EXIT);
  if (rate <= 0) {
    throw InputError(std::string(kSource), 0,
                     "cannot initialise espeak-ng (is espeak-ng-data installed? 'apt-get install espeak-ng-data')");
  }
  espeak_SetSynthCallback(collect);
  espeak_rate_hz = rate;
}

}  // namespace

Synthesis synthesize(std::string_view text, const SynthesisOptions& options) {
  const std::string source(kSource);
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) throw InputError(source, 0, "the text is empty");
  if (options.words_per_minute < 80 || options.words_per_minute > 450) {
    throw InputError(source, 0, "speaking rate " + std::to_string(options.words_per_minute) +
                                    " words per minute is out of range (80 to 450)");
  }
  const std::lock_guard lock(espeak_mutex);
  initialise_once();
  if (espeak_SetVoiceByName(options.voice.c_str()) != EE_OK) {
    throw InputError(source, 0, "unknown voice '" + options.voice + "' (see 'espeak-ng --voices')");
  }
  espeak_SetParameter(espeakRATE, options.words_per_minute, 0);

  Collector collector;
  const std::string text_z(text);  // espeak_Synth reads up to a terminating zero
  active_collector = &collector;
  const espeak_ERROR status = espeak_Synth(text_z.c_str(), text_z.size() + 1, 0, POS_CHARACTER, 0,
                                           espeakCHARS_UTF8, nullptr, nullptr);
  espeak_Synchronize();
  active_collector = nullptr;
  if (status != EE_OK) throw InputError(source, 0, "synthesis failed (espeak error " + std::to_string(status) + ")");

  Synthesis result;
  result.audio.sample_rate_hz = espeak_rate_hz;
  result.audio.samples = std::move(collector.samples);
  result.phonemes.source = source;
  result.phonemes.phone_set = "espeak";
  const auto total = static_cast<std::int64_t>(result.audio.samples.size());
  const auto to_us = [&](std::int64_t sample) { return sample * 1'000'000 / espeak_rate_hz; };
  std::int64_t previous_start = 0;
  for (std::size_t i = 0; i < collector.phonemes.size(); ++i) {
    const std::int64_t start = std::clamp<std::int64_t>(collector.phonemes[i].sample, previous_start, total);
    const std::int64_t end = i + 1 < collector.phonemes.size()
                                 ? std::clamp<std::int64_t>(collector.phonemes[i + 1].sample, start, total)
                                 : total;
    previous_start = start;
    if (end <= start) continue;  // a zero-length event (espeak marks some stress changes this way)
    result.phonemes.intervals.push_back(
        {collector.phonemes[i].name, to_us(start), to_us(end), static_cast<int>(i) + 1});
  }
  if (result.phonemes.intervals.empty()) throw InputError(source, 0, "espeak-ng produced no phonemes for the text");
  // The first phoneme starts at sample 0 and the phonemes tile the audio.
  if (result.phonemes.intervals.front().start_us > 0) {
    result.phonemes.intervals.insert(result.phonemes.intervals.begin(),
                                     {"", 0, result.phonemes.intervals.front().start_us, 0});
  }
  return result;
}

}  // namespace lipsync::speech
