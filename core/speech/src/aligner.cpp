// Forced alignment and phone recognition with PocketSphinx 5prealpha
// (lipsync/speech/aligner.hpp).
#include "lipsync/speech/aligner.hpp"

#include <pocketsphinx.h>
#include <sphinxbase/err.h>
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <sstream>

#include "alignable_audio.hpp"
#include "lipsync/error.hpp"
#include "pocketsphinx_words.hpp"

namespace lipsync::speech {
namespace {

using detail::add_word;
using detail::kBoundaryOffsetUs;
using detail::kFrameUs;
using detail::kPauseWord;
using detail::phone_of;

constexpr int kRateHz = 16000;
// Samples this close to full scale count as clipped; above this share of them a note says so.
constexpr std::int16_t kClippedLevel = 32700;
constexpr double kMostClippedShare = 0.001;

struct DecoderDeleter {
  void operator()(ps_decoder_t* decoder) const { ps_free(decoder); }
};
using Decoder = std::unique_ptr<ps_decoder_t, DecoderDeleter>;

bool is_file(const std::string& path) {
  struct stat info {};
  return ::stat(path.c_str(), &info) == 0 && S_ISREG(info.st_mode);
}

// What a decoder searches: the transcript's grammar, the phone loop, or English words.
enum class Search { forced, phones, words };

Decoder make_decoder(const AlignmentOptions& options, const std::string& source, Search search) {
  const bool forced = search == Search::forced;
  const std::string hmm = options.model_dir + "/en-us";
  const std::string dict = options.model_dir + "/cmudict-en-us.dict";
  for (const std::string& path : {hmm + "/mdef", dict}) {
    if (!is_file(path)) {
      throw InputError(
          source, 0,
          "the PocketSphinx model is missing (" + path + "; install it with 'apt-get install pocketsphinx-en-us')");
    }
  }
  err_set_logfp(nullptr);  // PocketSphinx logs to stderr by default; its failures come back as results here
  // Forced alignment searches a tiny grammar, so its beams can be all but open: with the
  // defaults (1e-48) the right path through synthetic speech is often pruned and nothing
  // fits. Pauses come only where the grammar allows them (between words), not as
  // fillers between any two of its one-phone words. Phone recognition uses the settings
  // the CMU Sphinx documentation gives for the phonetic LM (weight 2) with narrower beams
  // (1e-10 rather than 1e-20: about 1x real time instead of 2.5x, on espeak-ng speech).
  const char* beam = forced ? "1e-200" : "1e-10";
  cmd_ln_t* config = nullptr;
  if (search == Search::words) {
    const std::string word_lm = options.model_dir + "/en-us.lm.bin";
    // The defaults but at most 1500 HMMs active per frame (of 30000): on the 7.1 s LibriVox
    // recording the same words in 1.2 s instead of 1.9 s.
    config = cmd_ln_init(nullptr, ps_args(), TRUE, "-hmm", hmm.c_str(), "-dict", dict.c_str(), "-lm", word_lm.c_str(),
                         "-samprate", "16000", "-remove_silence", "no", "-maxhmmpf", "1500", nullptr);
  } else {
    config = cmd_ln_init(nullptr, ps_args(), TRUE, "-hmm", hmm.c_str(), "-dict", dict.c_str(), "-samprate", "16000",
                         "-remove_silence", "no", "-beam", beam, "-pbeam", beam, "-wbeam", beam, "-bestpath", "no",
                         "-fsgusefiller", "no", "-lw", forced ? "6.5" : "2.0", nullptr);
  }
  if (config == nullptr) throw InputError(source, 0, "cannot configure PocketSphinx");
  Decoder decoder(ps_init(config));
  cmd_ln_free_r(config);  // the decoder keeps its own reference
  if (!decoder) throw InputError(source, 0, "cannot load the PocketSphinx model from " + options.model_dir);
  return decoder;
}

// Share of the loud windows (within kLoudDb of the loudest) that the alignment labels as
// pause. A transcript that fits the audio leaves almost no speech in its pauses (stop
// closures are quiet); one that does not fit squeezes its words into a corner and calls
// the rest of the speech a pause.
constexpr double kLoudDb = 20.0;
constexpr double kMostSpeechInPauses = 0.3;
// Words the language model heard (no transcript) are kept only when they leave at most
// this share of the loud windows in pauses. On the accuracy bench's speech, words heard
// in flite's and Festival's sentences left at most 3 %, the garbled words heard in
// espeak-ng's 12 % or more (its formant synthesis is far from the model's voices).
constexpr double kMostSpeechInPausesOfHeardWords = 0.1;

double loud_share_in_pauses(const std::vector<double>& levels, double loudest,
                            const std::vector<LabeledInterval>& phones) {
  int loud = 0, loud_in_pause = 0;
  for (std::size_t w = 0; w < levels.size(); ++w) {
    if (levels[w] < loudest - kLoudDb) continue;
    ++loud;
    const std::int64_t centre_us = static_cast<std::int64_t>(w) * 20'000 + 10'000;
    const auto it = std::find_if(phones.begin(), phones.end(), [&](const LabeledInterval& phone) {
      return phone.start_us <= centre_us && centre_us < phone.end_us;
    });
    if (it != phones.end() && it->label.empty()) ++loud_in_pause;
  }
  return loud == 0 ? 0.0 : double(loud_in_pause) / loud;
}

std::string join_words(const std::vector<std::string>& words) {
  std::string text;
  for (const std::string& word : words) text += (text.empty() ? "" : " ") + word;
  return text;
}

std::string count_words(std::size_t n) { return std::to_string(n) + (n == 1 ? " word" : " words"); }

std::string lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

// The JSGF grammar of the transcript: each word's pronunciations as alternatives
// of one-phone words; an optional pause (PocketSphinx's silence phone) before, between
// and after the words, except after word w - 1 where no_pause_before[w] (w from 1).
std::string build_grammar(ps_decoder_t* decoder, const std::vector<std::string>& words, const std::string& source,
                          const std::vector<bool>& no_pause_before) {
  add_word(decoder, kPauseWord, "SIL");
  const std::string pause = " [ " + std::string(kPauseWord) + " ]";
  std::string rule = pause;
  for (std::size_t w = 0; w < words.size(); ++w) {
    const std::vector<std::string> pronunciations = detail::pronunciations(decoder, words[w]);
    if (pronunciations.empty()) {
      throw InputError(source, 0,
                       "transcript word " + std::to_string(w + 1) + " '" + words[w] +
                           "' is not in the pronouncing dictionary (write numbers and "
                           "abbreviations out as words)");
    }
    rule += " (";
    for (std::size_t p = 0; p < pronunciations.size(); ++p) {
      if (p > 0) rule += " |";
      std::istringstream phones(pronunciations[p]);
      for (std::string phone; phones >> phone;) {
        const std::string word = detail::phone_word(phone, w);
        add_word(decoder, word, phone);
        rule += " " + word;
      }
    }
    rule += " )";
    if (w + 1 == words.size() || !no_pause_before[w + 1]) rule += pause;
  }
  return "#JSGF V1.0;\ngrammar transcript;\npublic <utterance> =" + rule + " ;\n";
}

// Runs the decoder's current search over the audio; false when no path fits.
bool decode(ps_decoder_t* decoder, const PcmAudio& audio) {
  ps_start_utt(decoder);
  ps_process_raw(decoder, audio.samples.data(), audio.samples.size(), FALSE, TRUE);
  ps_end_utt(decoder);
  std::int32_t score = 0;
  return ps_get_hyp(decoder, &score) != nullptr;
}

// The decoded segments as phones (pauses and noises one silence, a silence before the
// first and after the last segment, so that they tile [0, the audio's end]) and words.
void read_segments(ps_decoder_t* decoder, const std::vector<std::string>& words, std::int64_t end_us,
                   Alignment& result) {
  std::vector<LabeledInterval>& phones = result.phones.intervals;
  phones.clear();
  result.words.clear();
  int word_index = -1;
  for (ps_seg_t* seg = ps_seg_iter(decoder); seg != nullptr; seg = ps_seg_next(seg)) {
    int first_frame = 0, last_frame = 0;
    ps_seg_frames(seg, &first_frame, &last_frame);
    const std::int64_t start = first_frame == 0 ? 0 : std::min(end_us, first_frame * kFrameUs + kBoundaryOffsetUs);
    const std::int64_t end = std::min(end_us, (last_frame + 1) * kFrameUs + kBoundaryOffsetUs);
    if (end <= start) continue;
    const std::string_view word = ps_seg_word(seg);
    if (word == "(NULL)") continue;  // an empty grammar arc, no audio
    auto [phone, index] = phone_of(word);
    if (!phones.empty() && phone.empty() && phones.back().label.empty()) {
      phones.back().end_us = end;  // adjacent pauses and noises are one silence
    } else {
      phones.push_back({phone, start, end, static_cast<int>(phones.size()) + 1});
    }
    if (index < 0) continue;
    if (index != word_index) {
      result.words.push_back({words[static_cast<std::size_t>(index)], start, end, index + 1});
      word_index = index;
    }
    result.words.back().end_us = end;
  }
  if (phones.empty() || phones.front().start_us > 0) {
    phones.insert(phones.begin(), {"", 0, phones.empty() ? end_us : phones.front().start_us, 0});
  }
  if (phones.back().end_us < end_us) phones.push_back({"", phones.back().end_us, end_us, int(phones.size()) + 1});
}

// A pause between two words that holds this many 20 ms windows of loud formants (the
// formant band's level within kLoudDb of its loudest window) or more is speech the
// recogniser could not fit, not a pause: vowels and glides are loud there, closures,
// voiced (their voicing bar is below the band) or not, are not.
constexpr int kLeastLoudWindowsOfSpeech = 3;
constexpr std::int64_t kWindowUs = 20'000;

// Which word gaps (w: between words w - 1 and w) hold a pause over speech, as above.
std::vector<bool> pauses_over_speech(const std::vector<double>& formant_levels, const Alignment& alignment) {
  std::vector<bool> over_speech(alignment.words.size(), false);
  if (formant_levels.empty()) return over_speech;
  const double loudest = *std::max_element(formant_levels.begin(), formant_levels.end());
  for (const LabeledInterval& pause : alignment.phones.intervals) {
    if (!pause.label.empty()) continue;
    int loud = 0;
    for (std::size_t w = 0; w < formant_levels.size(); ++w) {
      const std::int64_t centre_us = static_cast<std::int64_t>(w) * kWindowUs + kWindowUs / 2;
      if (pause.start_us <= centre_us && centre_us < pause.end_us && formant_levels[w] >= loudest - kLoudDb) ++loud;
    }
    const auto gap = static_cast<std::size_t>(
        std::count_if(alignment.words.begin(), alignment.words.end(),
                      [&](const LabeledInterval& word) { return word.end_us <= pause.start_us; }));
    if (loud >= kLeastLoudWindowsOfSpeech && gap > 0 && gap < over_speech.size()) over_speech[gap] = true;
  }
  return over_speech;
}

// Forced alignment of the transcript's words. Where the best path puts a pause over
// loud speech (espeak-ng's "lemons makes": a 230 ms pause over "makes", its /m ey/
// squeezed into 60 ms after it), the words around that pause were misplaced: the audio
// is decoded once more with no pause allowed in those gaps, and that alignment is kept
// when it fits and leaves no more of the loud windows in pauses than the first.
void force_align(ps_decoder_t* decoder, const PcmAudio& audio, const std::vector<std::string>& words,
                 const std::vector<double>& levels, const std::string& source, Alignment& result) {
  const auto use_grammar = [&](const char* name, const std::vector<bool>& no_pause_before) {
    const std::string grammar = build_grammar(decoder, words, source, no_pause_before);
    if (ps_set_jsgf_string(decoder, name, grammar.c_str()) != 0 || ps_set_search(decoder, name) != 0) {
      throw InputError(source, 0, "PocketSphinx rejected the transcript's grammar");
    }
  };
  use_grammar("transcript", std::vector<bool>(words.size(), false));
  if (!decode(decoder, audio)) {
    throw InputError(
        source, 0,
        "the transcript does not match the audio (no alignment of its " + count_words(words.size()) + " fits)");
  }
  read_segments(decoder, words, audio.duration_us(), result);
  const double loudest = *std::max_element(levels.begin(), levels.end());
  const double share = loud_share_in_pauses(levels, loudest, result.phones.intervals);
  const std::vector<bool> over_speech = pauses_over_speech(formant_band_levels_db(audio, kWindowUs, kWindowUs), result);
  // A transcript that does not fit leaves much speech in its pauses: that is an error
  // (align_speech), not something to force.
  if (share > kMostSpeechInPauses || std::find(over_speech.begin(), over_speech.end(), true) == over_speech.end()) {
    return;
  }
  use_grammar("transcript_without_pauses_over_speech", over_speech);
  if (!decode(decoder, audio)) return;
  Alignment second = result;
  read_segments(decoder, words, audio.duration_us(), second);
  if (loud_share_in_pauses(levels, loudest, second.phones.intervals) <= share) result = std::move(second);
}

// Phones recognised with the phonetic language model.
void recognise_phones(ps_decoder_t* decoder, const PcmAudio& audio, const AlignmentOptions& options,
                      const std::string& source, Alignment& result) {
  const std::string phone_lm = options.model_dir + "/en-us-phone.lm.bin";
  if (ps_set_allphone_file(decoder, "phones", phone_lm.c_str()) != 0 || ps_set_search(decoder, "phones") != 0) {
    throw InputError(source, 0, "cannot load the phonetic language model " + phone_lm);
  }
  if (!decode(decoder, audio)) throw InputError(source, 0, "no phones were recognised in the audio");
  read_segments(decoder, {}, audio.duration_us(), result);
}

// The words the English language model hears (en-us.lm.bin), lower case; none when it
// hears none or the model is missing.
std::vector<std::string> recognise_words(const PcmAudio& audio, const AlignmentOptions& options,
                                         const std::string& source) {
  if (!is_file(options.model_dir + "/en-us.lm.bin")) return {};
  const Decoder words = make_decoder(options, source, Search::words);
  ps_decoder_t* decoder = words.get();
  if (!decode(decoder, audio)) return {};
  std::int32_t score = 0;
  const char* hypothesis = ps_get_hyp(decoder, &score);
  return hypothesis == nullptr ? std::vector<std::string>() : transcript_words(hypothesis);
}

// Where the words heard in the recording do not fit, they are listened for once more in the
// recording over a faint white noise floor, this far below its loudest 20 ms window (RMS).
// The model was trained on recordings that all have a noise floor; a synthetic voice's
// digitally silent pauses and noiseless closures are far from anything it knows (log
// energies at the floor, cepstral means pulled by them). Of espeak-ng's first ten Harvard
// sentences (accuracy bench) 4 then fit, against none without the floor, and 5 of the next
// ten (none without). On the first listening the floor would cost words that fit without it
// (flite's 52 to 43 of 80 right, LibriVox's 51 to 48 of 71). 42 dB is uniform noise of 100
// LSB (-55 dBFS RMS) under espeak-ng's loudest windows (about -12.5 dBFS); 80 to 150 LSB
// measured about the same. The phone loop, where even those words do not fit, hears the
// same noisy copy: on espeak-ng's ten sentences 10 of 15 closures shown against 7 on the
// recording as it is, 56 % of the phonemes matched against 46 %, one false closure more.
constexpr double kNoiseFloorBelowLoudestDb = 42.0;

// `audio` plus uniform white noise with an RMS level `below_db` under `loudest_dbfs`, from a
// fixed-seed generator so that the same audio always gives the same words.
PcmAudio with_noise_floor(const PcmAudio& audio, double loudest_dbfs, double below_db) {
  PcmAudio noisy = audio;
  // Uniform noise in [-a, a] has an RMS of a / sqrt(3).
  const double amplitude = std::sqrt(3.0) * 32768.0 * std::pow(10.0, (loudest_dbfs - below_db) / 20.0);
  std::uint32_t state = 12345;
  for (std::int16_t& sample : noisy.samples) {
    state = state * 1664525U + 1013904223U;  // Numerical Recipes' linear congruential generator
    const double uniform = double(state >> 8) / double(1U << 24) * 2.0 - 1.0;
    sample = static_cast<std::int16_t>(std::clamp(sample + std::lround(uniform * amplitude), -32768L, 32767L));
  }
  return noisy;
}

// The heard words force-aligned as if they were the transcript (into `result`), when they fit
// the audio closely; false when they do not.
bool align_heard_words(const std::vector<std::string>& heard, const PcmAudio& audio, const std::vector<double>& levels,
                       const AlignmentOptions& options, const std::string& source, Alignment& result) {
  if (heard.empty()) return false;
  Alignment by_words = result;
  try {
    const Decoder forced = make_decoder(options, source, Search::forced);
    force_align(forced.get(), audio, heard, levels, source, by_words);
  } catch (const InputError&) {  // no alignment of the words fits
    return false;
  }
  const double loudest = *std::max_element(levels.begin(), levels.end());
  if (loud_share_in_pauses(levels, loudest, by_words.phones.intervals) > kMostSpeechInPausesOfHeardWords) return false;
  by_words.notes.push_back("no transcript: aligned to the words recognised (\"" + join_words(heard) + "\")");
  result = std::move(by_words);
  return true;
}

// Without a transcript: the words the English language model hears, force-aligned as
// if they were the transcript, where they fit the audio closely (heard in the recording
// as it is, else over a faint noise floor); the phone loop's phones (over that floor) where
// they do not. Every alignment's times are on the recording as it is.
void recognise_speech(const PcmAudio& audio, const std::vector<double>& levels, const AlignmentOptions& options,
                      const std::string& source, Alignment& result) {
  if (align_heard_words(recognise_words(audio, options, source), audio, levels, options, source, result)) return;
  const double loudest_dbfs = *std::max_element(levels.begin(), levels.end());
  const PcmAudio noisy = with_noise_floor(audio, loudest_dbfs, kNoiseFloorBelowLoudestDb);
  if (align_heard_words(recognise_words(noisy, options, source), audio, levels, options, source, result)) return;
  const Decoder phones = make_decoder(options, source, Search::phones);
  recognise_phones(phones.get(), noisy, options, source, result);
}

// How many phones (pauses aside) each word of `alignment` holds.
std::vector<std::size_t> phones_per_word(const Alignment& alignment) {
  std::vector<std::size_t> counts;
  for (const LabeledInterval& word : alignment.words) {
    counts.push_back(static_cast<std::size_t>(std::count_if(
        alignment.phones.intervals.begin(), alignment.phones.intervals.end(), [&](const LabeledInterval& phone) {
          return !phone.label.empty() && phone.start_us >= word.start_us && phone.end_us <= word.end_us;
        })));
  }
  return counts;
}

// After refine_closures: each word starts where its first phone starts now and ends where
// its last one ends (`phone_counts` from phones_per_word before it). The refiner moves
// boundaries and may give a pause before a /p b/ to the stop, which then starts where the
// pause did, inside the gap between two words; it keeps every phone and their order.
void fit_words_to_phones(const std::vector<std::size_t>& phone_counts, Alignment& alignment) {
  std::vector<const LabeledInterval*> spoken;
  for (const LabeledInterval& phone : alignment.phones.intervals) {
    if (!phone.label.empty()) spoken.push_back(&phone);
  }
  std::size_t next = 0;
  for (std::size_t w = 0; w < alignment.words.size(); ++w) {
    if (phone_counts[w] == 0 || next + phone_counts[w] > spoken.size()) return;
    alignment.words[w].start_us = spoken[next]->start_us;
    alignment.words[w].end_us = spoken[next + phone_counts[w] - 1]->end_us;
    next += phone_counts[w];
  }
}

}  // namespace

std::vector<std::string> transcript_words(std::string_view transcript) {
  std::vector<std::string> words;
  std::string word;
  for (const char c : transcript) {
    const auto u = static_cast<unsigned char>(c);
    if (std::isalnum(u) || c == '\'' || u >= 0x80) {
      word += static_cast<char>(std::tolower(u));
    } else if (!word.empty()) {
      words.push_back(std::move(word));
      word.clear();
    }
  }
  if (!word.empty()) words.push_back(std::move(word));
  // Quotes around a word are not part of it: 'hello' → hello, but don't stays.
  for (std::string& w : words) {
    while (!w.empty() && w.front() == '\'') w.erase(w.begin());
    while (!w.empty() && w.back() == '\'') w.pop_back();
  }
  std::erase_if(words, [](const std::string& w) { return w.empty(); });
  return words;
}

Alignment align_speech(const PcmAudio& input, std::string_view source_view, const AlignmentOptions& options) {
  const std::string source(source_view);
  Alignment result;
  result.phones.source = source;
  result.phones.phone_set = "arpabet";
  const std::vector<double> levels =
      detail::check_alignable_audio(input, source, options.max_duration_s, "speech recognition");
  const double loudest = *std::max_element(levels.begin(), levels.end());
  const auto clipped = std::count_if(input.samples.begin(), input.samples.end(),
                                     [](std::int16_t s) { return s >= kClippedLevel || s <= -kClippedLevel; });
  const double clipped_share = double(clipped) / double(input.samples.size());
  char clipped_text[96] = "";
  if (clipped_share > kMostClippedShare) {
    std::snprintf(clipped_text, sizeof clipped_text, "%.1f %% of the samples are clipped at full scale",
                  100.0 * clipped_share);
    result.notes.push_back(std::string(clipped_text) + " (the alignment may be less exact)");
  }
  if (input.sample_rate_hz != kRateHz) {
    result.notes.push_back("resampled from " + std::to_string(input.sample_rate_hz) + " Hz to 16000 Hz");
  }
  const PcmAudio audio = resample(input, kRateHz);

  std::vector<std::string> words;
  if (options.transcript) {
    words = transcript_words(*options.transcript);
    if (words.empty()) throw InputError(source, 0, "the transcript has no words");
  }
  if (options.transcript) {
    const Decoder decoder = make_decoder(options, source, Search::forced);
    force_align(decoder.get(), audio, words, levels, source, result);
  } else {
    recognise_speech(audio, levels, options, source, result);
  }
  std::vector<LabeledInterval>& phones = result.phones.intervals;
  if (options.refine_closures) {
    const std::vector<std::size_t> phone_counts = phones_per_word(result);
    result.refined = refine_closures(audio, result.phones, options.refiner);
    fit_words_to_phones(phone_counts, result);
  }
  if (options.transcript) {
    const double share = loud_share_in_pauses(levels, loudest, phones);
    if (share > kMostSpeechInPauses) {
      throw InputError(
          source, 0,
          "the transcript does not match the audio (its " + count_words(words.size()) + " fit only by leaving " +
              std::to_string(std::lround(100 * share)) + " % of the speech unaligned)" +
              (clipped_text[0] != 0 ? std::string("; ") + clipped_text + ", which drowns its quiet parts" : ""));
    }
  }
  return result;
}

void write_textgrid(std::ostream& out, const Alignment& alignment, std::int64_t duration_us) {
  const auto seconds = [](std::int64_t us) {
    char text[32];
    std::snprintf(text, sizeof text, "%.6f", double(us) / 1e6);
    return std::string(text);
  };
  const auto quoted = [](const std::string& text) {
    std::string q = "\"";
    for (const char c : text) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  // Word tier with silences filled in between the words, so that the intervals tile the tier.
  std::vector<LabeledInterval> word_tier;
  for (const LabeledInterval& word : alignment.words) {
    const std::int64_t previous_end = word_tier.empty() ? 0 : word_tier.back().end_us;
    if (word.start_us > previous_end) word_tier.push_back({"", previous_end, word.start_us, 0});
    word_tier.push_back(word);
  }
  if (!word_tier.empty() && word_tier.back().end_us < duration_us) {
    word_tier.push_back({"", word_tier.back().end_us, duration_us, 0});
  }
  std::vector<std::pair<std::string, const std::vector<LabeledInterval>*>> tiers;
  if (!word_tier.empty()) tiers.emplace_back("words", &word_tier);
  tiers.emplace_back("phones", &alignment.phones.intervals);

  out << "File type = \"ooTextFile\"\nObject class = \"TextGrid\"\n\n"
      << "xmin = 0\nxmax = " << seconds(duration_us) << "\ntiers? <exists>\nsize = " << tiers.size() << "\nitem []:\n";
  for (std::size_t t = 0; t < tiers.size(); ++t) {
    const auto& intervals = *tiers[t].second;
    out << "    item [" << t + 1 << "]:\n        class = \"IntervalTier\"\n        name = " << quoted(tiers[t].first)
        << "\n        xmin = 0\n        xmax = " << seconds(duration_us)
        << "\n        intervals: size = " << intervals.size() << "\n";
    for (std::size_t i = 0; i < intervals.size(); ++i) {
      out << "        intervals [" << i + 1 << "]:\n            xmin = " << seconds(intervals[i].start_us)
          << "\n            xmax = " << seconds(intervals[i].end_us)
          << "\n            text = " << quoted(intervals[i].label) << "\n";
    }
  }
}

namespace detail {

// Phone label of a recognised "word": "aa_3" → ("AA", 3); a phone from the
// phonetic LM ("AA") → ("AA", -1); silence and noise fillers → ("", -1).
std::pair<std::string, int> phone_of(std::string_view word) {
  if (word.empty() || word.front() == '<' || word.front() == '[' || word.front() == '+' || word == "SIL" ||
      word == kPauseWord) {
    return {"", -1};
  }
  int index = -1;
  if (const auto underscore = word.rfind('_'); underscore != std::string_view::npos) {
    index = std::atoi(std::string(word.substr(underscore + 1)).c_str());
    word = word.substr(0, underscore);
  }
  std::string phone(word);
  for (char& c : phone) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return {phone, index};
}

std::vector<std::string> pronunciations(ps_decoder_t* decoder, const std::string& word) {
  std::vector<std::string> found;
  for (int variant = 1; variant < 10; ++variant) {
    const std::string entry = variant == 1 ? word : word + "(" + std::to_string(variant) + ")";
    char* phones = ps_lookup_word(decoder, entry.c_str());
    if (phones == nullptr) break;
    found.emplace_back(phones);
    std::free(phones);
  }
  return found;
}

void add_word(ps_decoder_t* decoder, const std::string& word, const std::string& phones) {
  if (char* known = ps_lookup_word(decoder, word.c_str())) {
    std::free(known);
  } else {
    ps_add_word(decoder, word.c_str(), phones.c_str(), FALSE);
  }
}

std::string phone_word(const std::string& phone, std::size_t w) { return lower(phone) + "_" + std::to_string(w); }

}  // namespace detail

}  // namespace lipsync::speech
