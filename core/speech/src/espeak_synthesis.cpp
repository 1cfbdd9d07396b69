// espeak-ng synthesis with phoneme events, in this process (espeak_synthesis.hpp).
//
// espeak-ng reports each phoneme as an espeakEVENT_PHONEME event carrying its name and the sample
// at which it starts; the synthesis callback collects the samples and those events. A phoneme
// ends where the next one starts, the last one where the audio ends, so the intervals tile the
// audio exactly, on its own sample clock. Zero-length events (stress changes) are dropped. With
// IPA names, a language switch ("(en)" inside a Greek text) becomes silence, and a lone length
// mark or combining diacritic extends the phoneme before it instead of starting one.
//
// The text may be spoken in several runs (Mandarin characters and Latin words, espeak_readings.hpp),
// one espeak_Synth call each; espeak-ng counts samples and text positions from each call's start,
// so the collector adds the run's offsets. Its word events and the phonemes after each are judged
// at the end (judge_reading): a nonsense reading is refused, a doubtful one noted. A word event
// comes before the phonemes of its word (a pause after a word is among that word's phonemes), so
// each word of the text starts where the first phoneme after its first word event starts (a
// number read as several words gives several events inside one word of the text).
#include "espeak_synthesis.hpp"

#include <espeak-ng/espeak_ng.h>
#include <espeak-ng/speak_lib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "espeak_readings.hpp"
#include "espeak_voices.hpp"
#include "lipsync/error.hpp"

namespace lipsync::speech::detail {
namespace {

// espeak-ng's globals, in a worker process only: one initialisation per process.
int espeak_rate_hz = 0;  // 0 until initialised

struct PhonemeStart {
  std::string name;
  std::int64_t sample;
};

// What the callback collects during one espeak_Synth call.
struct Collector {
  std::vector<std::int16_t> samples;
  std::vector<PhonemeStart> phonemes;
  std::vector<SpokenWord> words;
  std::vector<std::size_t> words_first_phoneme;  // per word event: the index of the phoneme after it
  std::int64_t run_first_sample = 0;             // samples of the runs before this one
  std::size_t run_first_character = 0;           // code points of the text before this run
};
Collector* active_collector = nullptr;  // set during espeak_Synth

int collect(short* wav, int sample_count, espeak_EVENT* events) {
  Collector* collector = active_collector;
  if (collector == nullptr) return 0;
  if (wav != nullptr && sample_count > 0) collector->samples.insert(collector->samples.end(), wav, wav + sample_count);
  for (espeak_EVENT* event = events; event->type != espeakEVENT_LIST_TERMINATED; ++event) {
    if (event->type == espeakEVENT_PHONEME) {
      // `sample` is the event's position in the output, in samples (espeak-ng's
      // MarkerEvent); `audio_position` is the same in whole milliseconds.
      const std::string name(event->id.string, strnlen(event->id.string, sizeof event->id.string));
      collector->phonemes.push_back({name, collector->run_first_sample + event->sample});
      if (!collector->words.empty()) collector->words.back().phonemes.push_back(name);
    } else if (event->type == espeakEVENT_WORD) {
      // text_position: 1-based, in characters of this run's text; length: in characters.
      collector->words.push_back({collector->run_first_character + static_cast<std::size_t>(event->text_position),
                                  static_cast<std::size_t>(event->length),
                                  {}});
      collector->words_first_phoneme.push_back(collector->phonemes.size());
    }
  }
  return 0;  // continue synthesis
}

/// espeak-ng's IPA names mark a switch to another language's phonemes ("(en)" inside a Greek
/// text) as a phoneme of its own: silence, as its mnemonic _^_ is in the 'espeak' set.
bool is_language_switch(std::string_view name) { return name.size() >= 3 && name.front() == '(' && name.back() == ')'; }

/// A length mark or a combining diacritic that espeak-ng's IPA names give as a phoneme of its own
/// (lv, ltg, kok: "ː"; bpy: U+0303): it lengthens or colours the phoneme before it, so it extends
/// that phoneme's interval instead of starting one.
bool is_lone_mark(std::string_view name) {
  if (name == "ː" || name == "ˑ") return true;
  if (name.empty() || name.size() % 2 != 0) return false;
  for (std::size_t i = 0; i < name.size(); i += 2) {  // U+0300..U+036F: CC 80..BF, CD 80..AF
    const auto lead = static_cast<unsigned char>(name[i]);
    const auto next = static_cast<unsigned char>(name[i + 1]);
    if (!((lead == 0xCC && next >= 0x80 && next <= 0xBF) || (lead == 0xCD && next >= 0x80 && next <= 0xAF))) {
      return false;
    }
  }
  return true;
}

void initialise_once(bool ipa) {
  if (espeak_rate_hz > 0) return;
  const int rate = espeak_Initialize(
      AUDIO_OUTPUT_SYNCHRONOUS, 0, nullptr,
      espeakINITIALIZE_PHONEME_EVENTS | espeakINITIALIZE_DONT_EXIT | (ipa ? espeakINITIALIZE_PHONEME_IPA : 0));
  if (rate <= 0) {
    throw InputError(std::string(kEspeakSource), 0,
                     "cannot initialise espeak-ng (is espeak-ng-data installed? 'apt-get install espeak-ng-data')");
  }
  espeak_SetSynthCallback(collect);
  espeak_rate_hz = rate;
}

/// Selects `voice_name` for the next synthesis: a voice name or file, else a language ("en-gb",
/// "fr-fr": the Language column of espeak-ng --voices, which espeak_SetVoiceByName alone refuses)
/// resolved to its voice file, keeping a variant after '+'.
void select_voice(const std::string& voice_name) {
  bool found = espeak_SetVoiceByName(voice_name.c_str()) == EE_OK;
  if (const Voice* voice = found ? nullptr : find_voice(voice_name)) {
    const std::size_t plus = voice_name.find('+');
    const std::string variant = plus == std::string::npos ? "" : voice_name.substr(plus);
    found = espeak_SetVoiceByName((voice->identifier + variant).c_str()) == EE_OK;
  }
  if (!found) {
    throw InputError(std::string(kEspeakSource), 0, unknown_voice_text(voice_name));
  }
}

/// The collected phoneme starts as intervals that tile [0, the audio's end], in µs.
LabeledUtterance phoneme_intervals(const Collector& collector, bool english) {
  LabeledUtterance phonemes;
  phonemes.source = std::string(kEspeakSource);
  phonemes.phone_set = english ? "espeak" : "ipa";
  const auto total = static_cast<std::int64_t>(collector.samples.size());
  const auto to_us = [&](std::int64_t sample) { return sample * 1'000'000 / espeak_rate_hz; };
  std::int64_t previous_start = 0;
  for (std::size_t i = 0; i < collector.phonemes.size(); ++i) {
    const std::int64_t start = std::clamp<std::int64_t>(collector.phonemes[i].sample, previous_start, total);
    const std::int64_t end = i + 1 < collector.phonemes.size()
                                 ? std::clamp<std::int64_t>(collector.phonemes[i + 1].sample, start, total)
                                 : total;
    previous_start = start;
    if (end <= start) continue;  // a zero-length event (espeak marks some stress changes this way)
    const std::string& name = collector.phonemes[i].name;
    if (!english && is_lone_mark(name) && !phonemes.intervals.empty()) {
      phonemes.intervals.back().end_us = to_us(end);
      continue;
    }
    phonemes.intervals.push_back({!english && is_language_switch(name) ? std::string() : name, to_us(start), to_us(end),
                                  static_cast<int>(i) + 1});
  }
  if (phonemes.intervals.empty()) {
    throw InputError(std::string(kEspeakSource), 0, "espeak-ng produced no phonemes for the text");
  }
  // The first phoneme starts at sample 0 and the phonemes tile the audio.
  if (phonemes.intervals.front().start_us > 0) {
    phonemes.intervals.insert(phonemes.intervals.begin(), {"", 0, phonemes.intervals.front().start_us, 0});
  }
  return phonemes;
}

/// Where each word of `text` (as white space separates them) starts, µs on the audio's clock: the
/// start of the phoneme after its first word event (as phoneme_intervals() clamps it); -1 for a
/// word with no event or no phoneme after it.
std::vector<std::int64_t> word_starts(std::string_view text, const Collector& collector) {
  // Each code point's word (1-based positions, as the events count them); white space is no word.
  std::vector<std::int64_t> word_of_point(1, -1);
  std::int64_t words = 0;
  bool in_word = false;
  for (const char byte : text) {
    if ((static_cast<unsigned char>(byte) & 0xC0U) == 0x80U) continue;  // a UTF-8 continuation byte
    const bool space = byte == ' ' || byte == '\t' || byte == '\n' || byte == '\r' || byte == '\v' || byte == '\f';
    if (!space && !in_word) ++words;
    in_word = !space;
    word_of_point.push_back(space ? -1 : words - 1);
  }
  const auto total = static_cast<std::int64_t>(collector.samples.size());
  std::vector<std::int64_t> starts(static_cast<std::size_t>(words), -1);
  std::int64_t previous_start = 0;
  std::size_t next_phoneme = 0;
  for (std::size_t e = 0; e < collector.words.size(); ++e) {
    const std::size_t position = collector.words[e].position;
    const std::size_t phoneme = collector.words_first_phoneme[e];
    if (position >= word_of_point.size() || word_of_point[position] < 0 || phoneme >= collector.phonemes.size()) {
      continue;
    }
    // The phoneme's start as phoneme_intervals() clamps it: no earlier than the phonemes before it.
    for (; next_phoneme <= phoneme; ++next_phoneme) {
      previous_start = std::clamp<std::int64_t>(collector.phonemes[next_phoneme].sample, previous_start, total);
    }
    std::int64_t& start = starts[static_cast<std::size_t>(word_of_point[position])];
    if (start < 0) start = previous_start * 1'000'000 / espeak_rate_hz;
  }
  return starts;
}

}  // namespace

Synthesis synthesize_with_espeak(std::string_view text, const SynthesisOptions& options) {
  const bool english = speaks_english(options.voice);
  initialise_once(!english);
  const Voice* voice = find_voice(options.voice);
  // The cmn voice reads the pinyin of its own dictionary by English rules: characters go to its
  // pinyin variant (espeak_readings.hpp).
  const Voice* pinyin = voice != nullptr && voice->identifier == "sit/cmn" ? find_voice("cmn-latn-pinyin") : nullptr;
  const std::string prepared = prepare_text(text);
  const std::size_t plus = options.voice.find('+');
  const std::string variant = plus == std::string::npos ? "" : options.voice.substr(plus);
  const std::vector<TextRun> runs =
      split_runs(prepared, options.voice, pinyin != nullptr ? pinyin->identifier + variant : std::string());

  Collector collector;
  for (const TextRun& run : runs) {
    select_voice(run.voice);
    espeak_SetParameter(espeakRATE, options.words_per_minute, 0);
    collector.run_first_sample = static_cast<std::int64_t>(collector.samples.size());
    collector.run_first_character = run.first_character;
    const std::string text_z(run.text);  // espeak_Synth reads up to a terminating zero
    active_collector = &collector;
    const espeak_ERROR status =
        espeak_Synth(text_z.c_str(), text_z.size() + 1, 0, POS_CHARACTER, 0, espeakCHARS_UTF8, nullptr, nullptr);
    espeak_Synchronize();
    active_collector = nullptr;
    if (status != EE_OK) {
      throw InputError(std::string(kEspeakSource), 0, "synthesis failed (espeak error " + std::to_string(status) + ")");
    }
  }
  const std::string language = voice != nullptr && !voice->languages.empty() ? voice->languages.front() : "";
  ReadingVerdict verdict = judge_reading(prepared, collector.words, options.voice, language);
  if (!verdict.refusal.empty()) throw InputError(std::string(kEspeakSource), 0, verdict.refusal);

  Synthesis result;
  result.phonemes = phoneme_intervals(collector, english);
  result.word_starts_us = word_starts(prepared, collector);
  result.audio.sample_rate_hz = espeak_rate_hz;
  result.audio.samples = std::move(collector.samples);
  result.notes = std::move(verdict.notes);
  return result;
}

}  // namespace lipsync::speech::detail
