// Alignment of a recording against espeak-ng's rendering of its transcript by
// dynamic time warping of MFCC frames (lipsync/speech/dtw_aligner.hpp).
#include "lipsync/speech/dtw_aligner.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

#include "alignable_audio.hpp"
#include "lipsync/error.hpp"

namespace lipsync::speech {
namespace {

// Frames this far below the loudest are taken as pause when finding where speech starts and ends.
constexpr double kSpeechRangeDb = 35.0;
// The shortest a carried phoneme may become, µs.
constexpr std::int64_t kMinPhoneUs = 1'000;
// Silence added before and after espeak-ng's audio (which starts speaking at once), so the
// recording's leading and trailing pauses have pause to match, µs.
constexpr std::int64_t kSynthesisPaddingUs = 300'000;
// How far before espeak-ng's start of a stop its closure is looked for, µs.
constexpr std::int64_t kStopClosureSearchUs = 150'000;
// The smallest fall of the formant band's level taken as a stop's closure, dB.
constexpr double kStopClosureStepDb = 10.0;
// A stop after a pause has no fall of the level to mark its closure, in either audio (both
// start it at the burst): its closure is taken to last this long, a typical closure of a stop
// that begins an utterance (longer than espeak-ng's closures between vowels), µs.
constexpr std::int64_t kClosureAfterPauseUs = 80'000;
// A stop after a nasal (/m b/, /n d/) has no fall of the level to mark its closure either: the
// nasal's closure goes on into it, and espeak-ng's nasal lasts until the burst. Its closure is taken
// to last this long, a typical closure of a voiced stop (chosen on the four sentences of Italian
// and Hindi whose /m b/ arrived at their bursts, 58 and 73 ms after Festival's closures), µs.
constexpr std::int64_t kClosureAfterNasalUs = 60'000;
// The recording may be this many times longer or shorter than the synthesis.
constexpr double kMostDurationRatio = 4.0;
// A recording's pause: at least this long at a level kSpeechRangeDb under its loudest, µs.
constexpr std::int64_t kLeastPauseUs = 120'000;
// A pause of the recording that the warp matches to this much less pause of the rendering is
// put into the rendering, µs.
constexpr std::int64_t kLeastMissingPauseUs = 100'000;
// A pause of the rendering that the warp matches to this much less pause of the recording is cut
// from the rendering, µs. espeak-ng pauses between some words where a speaker runs on (110 ms after
// Catalan "pomes" before "i peres", and after Finnish "maitoa" before "ja banaaneja"); the warp then
// gives that digital silence to the next closure of the recording as quiet as it, and shifts the
// phones after by one: the /p/ of "peres" came 193 ms late, the /b/ of "banaaneja" 199 ms. With the
// pause cut (and the warp done again) they are 2 and 1 ms late, and Catalan's /u b/ of "Obrim" 11 ms
// early instead of 38; four other closures move 2 to 20 ms, none past 30. espeak-ng's short pauses between words
// (10 to 25 ms) stay.
constexpr std::int64_t kLeastExtraPauseUs = 50'000;

// A voiced /b/ whose carried start lies inside a voiced closure of the recording starts where that
// closure does (start_voiced_bilabials_at_closures): the closure is the formant band (400–3500 Hz)
// this much under the sound before it and the sound after it (the release), dB,
constexpr double kVoicedClosureDb = 10.0;
// its frames within this much of the formant band's level at the carried start, dB,
constexpr double kVoicedClosureSpreadDb = 6.0;
// voiced: the level below 400 Hz (the voicing bar) at most this much under its loudest in the
// recording, dB, and not falling by kVoicedClosureDb from the carried start back; looked for this
// far each side of the carried start, ms; the phones it crosses are left this long before it, µs.
constexpr double kVoicingBarRangeDb = 25.0;
constexpr std::int64_t kVoicedClosureSearchMs = 150;
constexpr std::int64_t kSqueezedPhoneUs = 10'000;
// A closure this short is a tap's (Catalan's /ɾ/: the formant band dips for 20 to 25 ms), not a /b/'s
// (60 to 90 ms in Festival's Catalan), ms.
constexpr std::int64_t kShortestVoicedClosureMs = 40;

enum Step : std::uint8_t { kDiagonal, kDown, kRight };
// Marks a stored step that paid StretchCost::cost (a → or ↓ past a run's free frames).
constexpr std::uint8_t kStretched = 4;

double frame_distance(const FeatureFrames& a, std::size_t i, const FeatureFrames& b, std::size_t j) {
  const float* x = a.frame(i);
  const float* y = b.frame(j);
  double sum = 0.0;
  for (int d = 0; d < a.dimensions; ++d) {
    const double difference = x[d] - y[d];
    sum += difference * difference;
  }
  return std::sqrt(sum);
}

// The column of the band's centre line at row i: piecewise linear through the corners and
// the starts and ends of speech.
double centre_column(std::size_t i, const std::size_t (&rows)[4], const std::size_t (&columns)[4]) {
  for (int piece = 0; piece < 3; ++piece) {
    if (i <= rows[piece + 1] || piece == 2) {
      const double span = static_cast<double>(rows[piece + 1]) - static_cast<double>(rows[piece]);
      const double t = span <= 0 ? 1.0 : (static_cast<double>(i) - static_cast<double>(rows[piece])) / span;
      return static_cast<double>(columns[piece]) +
             t * (static_cast<double>(columns[piece + 1]) - static_cast<double>(columns[piece]));
    }
  }
  return static_cast<double>(columns[3]);
}

bool has_word_character(std::string_view text) {
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte >= 0x80 || std::isalnum(byte)) return true;
  }
  return false;
}

// A label of espeak-ng (mnemonic or IPA) that begins with an oral closure: a plosive or an
// affricate (p, b, t, d, k, g, c, ɟ, q, ʈ, ɖ with any marks: "tʃ", "kʰ", "t#", "dZ").
bool starts_with_closure(const std::string& label) {
  if (label.empty()) return false;
  if (std::string_view("pbtdkgcq").find(label.front()) != std::string_view::npos) return true;
  return label.starts_with("ɟ") || label.starts_with("ʈ") || label.starts_with("ɖ");
}

// The ARPAbet lip phone a label of espeak-ng (mnemonic or IPA) stands for, for the closure
// refiner: p b m f v, alone or with length marks and diacritics ("pʰ", "mː", "b:"); else "X".
// A /β/ is a /b/ too: espeak-ng says Catalan's and Spanish's /b/ between vowels as a fricative
// that the recording (Festival's Catalan) may close.
std::string lip_phone_for_refiner(const std::string& label) {
  if (label.empty()) return label;
  if (label.starts_with("β")) return "B";
  const char first = label.front();
  if (first != 'p' && first != 'b' && first != 'm' && first != 'f' && first != 'v') {
    return starts_with_closure(label) ? "T" : "X";  // the refiner finds a /p b/'s closure after a stop apart
  }
  if (label.size() > 1 && std::isalpha(static_cast<unsigned char>(label[1]))) return "X";  // "pf", "ts"…
  return std::string(1, static_cast<char>(std::toupper(static_cast<unsigned char>(first))));
}

// Runs the closure refiner on `phones` (labels of espeak-ng) through their ARPAbet stand-ins. The
// refiner may give a short pause before a /p b/ to the stop (its closure, heard as silence) and drop
// it: each stand-in carries the index of its phone in `line`, so the labels follow their intervals.
std::vector<RefinedBoundary> refine_lip_phones(const PcmAudio& audio, LabeledUtterance& phones,
                                               const ClosureRefinerOptions& options) {
  LabeledUtterance stand_in = phones;
  for (std::size_t i = 0; i < stand_in.intervals.size(); ++i) {
    stand_in.intervals[i].label = lip_phone_for_refiner(phones.intervals[i].label);
    stand_in.intervals[i].line = static_cast<int>(i);
  }
  std::vector<RefinedBoundary> refined = refine_closures(audio, stand_in, options);
  std::vector<LabeledInterval> intervals;
  intervals.reserve(stand_in.intervals.size());
  for (const LabeledInterval& interval : stand_in.intervals) {
    const LabeledInterval& phone = phones.intervals[static_cast<std::size_t>(interval.line)];
    intervals.push_back({phone.label, interval.start_us, interval.end_us, phone.line});
  }
  phones.intervals = std::move(intervals);
  return refined;
}

// A nasal of espeak-ng (mnemonic or IPA): m n ŋ ɲ ɳ ɱ ("N" in the English mnemonics), with any marks.
bool is_nasal(const std::string& label) {
  if (label.empty()) return false;
  if (label.front() == 'm' || label.front() == 'n' || label.front() == 'N') return true;
  return label.starts_with("ŋ") || label.starts_with("ɲ") || label.starts_with("ɳ") || label.starts_with("ɱ");
}

// A closure that is voiced from its start: a nasal, or a voiced stop or affricate (b d g ɡ ɟ ɖ ɢ,
// with any marks: "bʲ", "dʒ", "dZ").
bool is_voiced_closure(const std::string& label) {
  if (is_nasal(label)) return true;
  if (label.empty()) return false;
  if (std::string_view("bdg").find(label.front()) != std::string_view::npos) return true;
  return label.starts_with("ɡ") || label.starts_with("ɟ") || label.starts_with("ɖ") || label.starts_with("ɢ");
}

// The steepest fall of the formant band's level (`level_db`, 10 ms windows every ms) within
// [earliest_ms, start_ms − 5 ms] larger than kStopClosureStepDb: a stop's closure before its
// burst at start_ms; −1 when there is none.
std::int64_t closure_before_ms(const std::vector<double>& level_db, std::int64_t start_ms, std::int64_t earliest_ms) {
  double best_fall_db = kStopClosureStepDb;
  std::int64_t best_ms = -1;
  for (std::int64_t t = std::max<std::int64_t>(earliest_ms, 10);
       t <= start_ms - 5 && t < static_cast<std::int64_t>(level_db.size()); ++t) {
    const double fall = level_db[t - 10] - level_db[t];
    if (fall > best_fall_db) {
      best_fall_db = fall;
      best_ms = t;
    }
  }
  return best_ms;
}

// espeak-ng starts a stop's phoneme event at its burst, the closure's silence still counted in
// the phoneme before. Each stop's start moves back to the steepest fall of the formant band's
// level within kStopClosureSearchUs before it (the closure), when the fall is clear, so that
// what is carried to the recording is where the stop begins, as in a recording's labels. Returns
// every phoneme's start before the move (a stop's burst).
std::vector<std::int64_t> move_stop_starts_to_closures(const PcmAudio& audio, LabeledUtterance& phones) {
  std::vector<LabeledInterval>& intervals = phones.intervals;
  std::vector<std::int64_t> bursts_us;
  bursts_us.reserve(intervals.size());
  for (const LabeledInterval& interval : intervals) bursts_us.push_back(interval.start_us);
  const std::vector<double> level_db = formant_band_levels_db(audio, 10'000, 1'000);  // window [t, t+10 ms)
  if (level_db.size() < 20) return bursts_us;
  for (std::size_t k = 1; k < intervals.size(); ++k) {
    if (!starts_with_closure(intervals[k].label)) continue;
    const std::int64_t start_ms = intervals[k].start_us / 1000;
    const std::int64_t best_ms = closure_before_ms(
        level_db, start_ms, std::max(start_ms - kStopClosureSearchUs / 1000, intervals[k - 1].start_us / 1000 + 10));
    if (best_ms < 0) continue;
    intervals[k].start_us = best_ms * 1000;
    intervals[k - 1].end_us = best_ms * 1000;
  }
  return bursts_us;
}

// A stop after a pause starts, in both audios, at its burst: the closure is silent, like the pause.
// Its start moves back into the pause by kClosureAfterPauseUs (the pause keeps kMinPhoneUs at least).
void open_closures_after_pauses(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones) {
  for (std::size_t k = 1; k < phones.size(); ++k) {
    if (!phones[k - 1].label.empty() || !starts_with_closure(phones[k].label)) continue;
    bounds[k] = std::max(bounds[k] - kClosureAfterPauseUs, bounds[k - 1] + kMinPhoneUs);
  }
}

// A stop after a nasal arrives at (or just before) the recording's burst: its closure is the nasal's
// and shows no fall of the level. It starts kClosureAfterNasalUs before its burst carried across,
// unless it is earlier already (the nasal keeps kMinPhoneUs at least).
void open_closures_after_nasals(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                const std::vector<std::int64_t>& bursts_us, const WarpPath& path) {
  for (std::size_t k = 1; k < phones.size(); ++k) {
    if (!is_nasal(phones[k - 1].label) || !starts_with_closure(phones[k].label)) continue;
    const std::int64_t closure_us = carry_time_us(path, bursts_us[k]) - kClosureAfterNasalUs;
    bounds[k] = std::max(std::min(bounds[k], closure_us), bounds[k - 1] + kMinPhoneUs);
  }
}

// A nasal or a voiced stop after a pause is heard from where the recording leaves pause level: the
// nasal's murmur or the stop's voicing bar, under a closure that espeak-ng's rendering starts
// softer or later, so that the warp carries its start into the recording's murmur. Such a phone
// whose carried start is in the recording's speech, with pause-level frames within
// kClosureAfterPauseUs before it, starts after the last of those. (Russian "Бабушка" after the
// leading pause: 55 ms late, then 1 ms early; eight other /m/ after a pause, in four voices, move
// 2 to 11 ms nearer Festival's labels. Applied to every phone after a pause, it moved espeak-ng's
// own fricatives and vowels before their labels: the 120-wpm test's p95 went 26.7 to 32.3 ms.)
void start_at_speech_after_pauses(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                  const std::vector<bool>& recording_quiet) {
  for (std::size_t k = 1; k < phones.size(); ++k) {
    if (!phones[k - 1].label.empty() || !is_voiced_closure(phones[k].label) || recording_quiet.empty()) continue;
    const auto frame_at = [&](std::int64_t us) {
      const std::int64_t frame = (us - feature_frame_centre_us(0) + kFeatureHopUs / 2) / kFeatureHopUs;
      return static_cast<std::size_t>(std::clamp<std::int64_t>(frame, 0, std::int64_t(recording_quiet.size()) - 1));
    };
    std::size_t frame = frame_at(bounds[k]);
    if (recording_quiet[frame]) continue;
    while (frame > 0 && !recording_quiet[frame - 1] &&
           bounds[k] - feature_frame_centre_us(frame - 1) <= kClosureAfterPauseUs) {
      --frame;
    }
    if (frame == 0 || !recording_quiet[frame - 1]) continue;
    const std::int64_t onset_us = feature_frame_centre_us(frame) - kFeatureHopUs / 2;
    bounds[k] = std::max(std::min(bounds[k], onset_us), bounds[k - 1] + kMinPhoneUs);
  }
}

// A label of espeak-ng (IPA or English mnemonic) that is a vowel or a diphthong: its first letter is
// one of a e i o u y, an IPA vowel letter, or a mnemonic vowel (@ 3 V I U O A E).
bool is_vowel(const std::string& label) {
  if (label.empty()) return false;
  if (std::string_view("aeiouy@3VIUOAE").find(label.front()) != std::string_view::npos) return true;
  for (const std::string_view vowel :
       {"ɑ", "ɐ", "ɒ", "æ", "ɛ", "ɜ", "ə", "ɘ", "ɵ", "ɞ", "ɤ", "ɨ", "ɪ", "ʊ", "ʌ", "ɔ", "ø", "œ", "ɯ", "ʉ", "ʏ", "ɶ"}) {
    if (label.starts_with(vowel)) return true;
  }
  return false;
}

// An /m/'s murmur is quieter than the vowel before it in the formant band (400–3500 Hz): the lips are
// closed and the sound leaves through the nose. espeak-ng's short vowels are farther from a speaker's
// than its /m/ is, so the warp may match /m/ frames to the end of the recording's vowel (Russian "в
// большом" /o m/: two /m/ frames took 100 ms of Festival's /o/ in runs of 5 and 8 frames, within the
// run cost's free frames; the /m/ was 104 ms early). An /m/ after a vowel whose carried start is
// inside the vowel (the level there within kMurmurInVowelDb of the loudest from the vowel's carried
// start to kMurmurInVowelUs after it, and falling by no more than kMurmurSteadyDb over those
// kMurmurInVowelUs) starts where the level first falls kMurmurFallDb under that loudest, at the steepest 10 ms fall
// within 10 ms of that, when this is inside its carried interval and within kMurmurSearchUs of its start. The Russian
// /m/ is then 9 ms late; no other /p b m/ of the seven voices moves (each /m/ there starts at a falling level already;
// without the check that the level is not falling, Catalan's /ə m/ of "Em poso", whose level falls slowly into the
// murmur, went from 11 ms early to 72 ms late). Applied to every nasal, it moved Czech "Maminka" /ŋ/ before its /k/
// from 43 ms early to 46 ms late: a velar nasal's murmur keeps the formant band up until the stop's closure.
constexpr double kMurmurInVowelDb = 4.0;
constexpr double kMurmurSteadyDb = 2.0;
constexpr std::int64_t kMurmurInVowelUs = 30'000;
constexpr double kMurmurFallDb = 6.0;
constexpr std::int64_t kMurmurSearchUs = 150'000;

// A fricative or affricate of espeak-ng (mnemonic or IPA), with any marks: its own sound is low in the
// formant band and may be voiced, like a closure.
bool is_fricative_or_affricate(const std::string& label) {
  if (label.empty()) return false;
  static constexpr std::string_view kAscii = "fvszhxTDSZC";  // T D S Z C: the mnemonics' θ ð ʃ ʒ ç
  static constexpr std::string_view kIpa[] = {"θ", "ð", "ʃ", "ʒ", "ç", "ʝ", "ɣ", "χ", "ʁ", "ħ", "ʕ",
                                              "ɸ", "β", "ʂ", "ʐ", "ɕ", "ʑ", "ɬ", "ɮ", "ʦ", "ʧ", "ʤ"};
  const auto starts_fricative = [&](std::string_view rest) {
    if (!rest.empty() && kAscii.find(rest.front()) != std::string_view::npos) return true;
    return std::any_of(std::begin(kIpa), std::end(kIpa), [&](std::string_view f) { return rest.starts_with(f); });
  };
  if (starts_fricative(label)) return true;
  // An affricate: a stop followed by a fricative ("ts", "tʃ", "dʑ", "dZ", "pf").
  return starts_with_closure(label) && label.size() > 1 && starts_fricative(std::string_view(label).substr(1));
}

// A phone whose sound would end a closure if it were said there: a vowel, a liquid or glide, or a stop
// (whose closure a following /b/ shares). A voiced closure may hold such phones of espeak-ng's that the
// speaker left out or that the warp pushed into it; a pause, nasal or fricative is a closure-like sound
// of its own.
bool may_be_squeezed_into_closure(const std::string& label) {
  return !label.empty() && !is_nasal(label) && !is_fricative_or_affricate(label);
}

}  // namespace

// A voiced /b/ (espeak-ng's /b/, or the /β/ it says for Catalan's and Spanish's /b/ between vowels and
// after some consonants) whose carried start lies inside a voiced closure of the recording starts where
// that closure begins, and the phones of espeak-ng's the warp put inside the closure before it are
// squeezed against it. Festival's Catalan speaker says "molt bo", "al bosc", "el bon" as [l b] with no
// /t/ or vowel between: espeak-ng's [l t β], [ɐ l β] and the quiet closure of its /t/ took the start of
// the recording's closure, and the /β/, a fricative as loud as a vowel in espeak-ng's audio, went to
// the burst, 37 to 66 ms late, out of the closure refiner's reach (it looks 50 ms around the warp's
// boundary, and not before the phone before). The closure shows in the sound: the formant band falls
// 13 to 21 dB and stays down to the burst, while the level below 400 Hz (the voicing bar) holds within
// 6 dB of the /l/'s. So: where the formant band at the carried start is kVoicedClosureDb under both the
// sound before and the release after, and the low band within kVoicingBarRangeDb of its loudest
// (voiced), the closure is followed back while the formant band stays within kVoicedClosureSpreadDb of
// that level and the voicing bar holds. It begins at a fall of the formant band (the /b/ starts at that
// fall's onset, where it is down to 0.4 of its steepest, less 3 ms, as the closure refiner places a
// closure), or, after a voiceless stop's silence, where the voicing bar rises ("barret blau": Festival
// says [t b], the /t/'s silence and then 75 ms of voicing bar; the /β/ was 73 ms late). Only stops and
// sonorants may lie in the closure: a voiced fricative or nasal before the /b/ is low in the formant
// band and voiced too (Russian "в большом" /v b/). A voiceless closure is left alone: a /p b/ after a
// stop with no release shares one silence with it (Finnish "menivat puistoon"), where the speaker
// closes the lips is not heard. A dip shorter than kShortestVoicedClosureMs is a tap's. Measured on
// Festival's voices (the signed errors against Festival's labels): Catalan held out, all six
// sentences, 78 -> 89 % of 36 /p b m/ within 30 ms ("al bosc", "molt bo", "el bon" /l b/ +37, +57,
// +38 -> -2, -4, -4 ms; "barret blau" /t b/ +73 -> +2; p95 58 -> 51 ms), the first two 92 -> 100 %
// of 12, in sample 93 -> 100 % of 29 ("molt bonica" /l b/ +66 -> -4, "mar blau" /r b/ +32 -> -11);
// Russian "большой белый" /j bʲ/ +27 -> -1 ms (its median in sample 21 -> 20 ms); no other closure
// of any voice moves, in sample or held out.
void start_voiced_bilabials_at_closures(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                        const PcmAudio& recording) {
  // The recording's levels in the formant band and below 400 Hz, dB, of the 10 ms windows
  // [t, t + 10 ms) at every millisecond t.
  const std::vector<double> formants = formant_band_levels_db(recording, 10'000, 1'000);
  const std::vector<double> lows = low_band_levels_db(recording, 10'000, 1'000);
  const auto n = static_cast<std::int64_t>(formants.size());
  if (n == 0 || lows.size() != formants.size() || bounds.size() != phones.size() + 1) return;
  // The levels of the 10 ms window centred at t ms.
  const auto formant = [&](std::int64_t t) { return formants[std::clamp<std::int64_t>(t - 5, 0, n - 1)]; };
  const auto low = [&](std::int64_t t) { return lows[std::clamp<std::int64_t>(t - 5, 0, n - 1)]; };
  const auto loudest_formant = [&](std::int64_t from, std::int64_t to) {
    double loudest = -1e300;
    for (std::int64_t t = from; t < to; ++t) loudest = std::max(loudest, formant(t));
    return loudest;
  };
  const double loudest_low = *std::max_element(lows.begin(), lows.end());
  for (std::size_t k = 2; k + 1 < phones.size(); ++k) {
    if (lip_phone_for_refiner(phones[k].label) != "B" || phones[k - 1].label.empty() || is_nasal(phones[k - 1].label))
      continue;
    const std::int64_t t0 = bounds[k] / 1000;
    const double closure_db = formant(t0), voicing_db = low(t0);
    if (voicing_db < loudest_low - kVoicingBarRangeDb) continue;
    const auto in_closure = [&](std::int64_t t) { return formant(t) <= closure_db + kVoicedClosureSpreadDb; };
    std::int64_t release = t0;
    while (release < t0 + kVoicedClosureSearchMs && in_closure(release + 1)) ++release;
    if (release >= t0 + kVoicedClosureSearchMs ||
        loudest_formant(release, release + 20) - closure_db < kVoicedClosureDb) {
      continue;
    }
    std::int64_t begin = t0;
    while (begin > t0 - kVoicedClosureSearchMs && in_closure(begin - 1) &&
           low(begin - 1) >= voicing_db - kVoicedClosureDb)
      --begin;
    if (begin <= t0 - kVoicedClosureSearchMs || release - begin < kShortestVoicedClosureMs) continue;
    std::int64_t start_ms = 0;
    if (!in_closure(begin - 1)) {  // the formant band's fall from the sound before
      if (loudest_formant(begin - 20, begin) - closure_db < kVoicedClosureDb) continue;
      const auto fall = [&](std::int64_t t) { return formant(t - 5) - formant(t + 5); };
      std::int64_t steepest = begin - 20;
      for (std::int64_t t = begin - 20; t <= begin + 10; ++t) {
        if (fall(t) > fall(steepest)) steepest = t;
      }
      std::int64_t onset = steepest;
      while (onset - 1 > begin - 40 && fall(onset - 1) >= 0.4 * fall(steepest)) --onset;
      start_ms = onset - 3;
    } else {  // the voicing bar's rise in a voiceless stop's silence
      std::int64_t silence = begin;
      while (silence > t0 - kVoicedClosureSearchMs && in_closure(silence - 1)) --silence;
      if (silence <= t0 - kVoicedClosureSearchMs ||
          loudest_formant(silence - 20, silence) - closure_db < kVoicedClosureDb) {
        continue;
      }
      const auto rise = [&](std::int64_t t) { return low(t + 5) - low(t - 5); };
      std::int64_t steepest = silence;
      for (std::int64_t t = silence; t <= begin + 10; ++t) {
        if (rise(t) > rise(steepest)) steepest = t;
      }
      start_ms = steepest;
    }
    const std::int64_t start_us = start_ms * 1000;
    if (start_us >= bounds[k]) continue;
    // The phone holding the closure's start and those after it, up to the /b/, must be ones that a
    // closure may hold; those after it are squeezed before the /b/.
    std::size_t holder = k - 1;
    while (holder > 0 && bounds[holder] > start_us) --holder;
    bool squeezable = true;
    for (std::size_t j = holder; j < k; ++j) squeezable = squeezable && may_be_squeezed_into_closure(phones[j].label);
    const auto crossed = static_cast<std::int64_t>(k - 1 - holder);
    std::int64_t spacing = kSqueezedPhoneUs;
    if (start_us - crossed * spacing < bounds[holder] + kSqueezedPhoneUs) spacing = kMinPhoneUs;
    if (!squeezable || start_us - crossed * spacing < bounds[holder] + kMinPhoneUs) continue;
    bounds[k] = start_us;
    for (std::size_t j = k - 1; j > holder; --j) bounds[j] = bounds[j + 1] - spacing;
  }
}

namespace {

// The boundaries of `phones` (espeak-ng's, stops from their closures) carried across the warp to a
// recording of `end_us`, in order and at least kMinPhoneUs apart, with the closures of stops after a
// pause or a nasal opened and sounds after a pause started at the recording's speech: bounds[k] is
// the start of phones[k], bounds[size] the end.
std::vector<std::int64_t> carried_bounds(const WarpPath& path, const std::vector<LabeledInterval>& phones,
                                         const std::vector<std::int64_t>& bursts_us, std::int64_t end_us,
                                         const std::vector<bool>& recording_quiet, const PcmAudio& recording) {
  const std::size_t count = phones.size();
  std::vector<std::int64_t> bounds(count + 1);
  bounds[0] = 0;
  bounds[count] = end_us;
  for (std::size_t k = 1; k < count; ++k) bounds[k] = carry_time_us(path, phones[k].start_us);
  for (std::size_t k = 1; k < count; ++k) bounds[k] = std::max(bounds[k], bounds[k - 1] + kMinPhoneUs);
  for (std::size_t k = count; k-- > 1;) bounds[k] = std::min(bounds[k], bounds[k + 1] - kMinPhoneUs);
  open_closures_after_pauses(bounds, phones);
  start_at_speech_after_pauses(bounds, phones, recording_quiet);
  open_closures_after_nasals(bounds, phones, bursts_us, path);
  start_voiced_bilabials_at_closures(bounds, phones, recording);
  return bounds;
}

// `audio` with kSynthesisPaddingUs of silence before and after.
PcmAudio padded(const PcmAudio& audio) {
  const auto padding = static_cast<std::size_t>(audio.sample_rate_hz * kSynthesisPaddingUs / 1'000'000);
  PcmAudio result{audio.sample_rate_hz, std::vector<std::int16_t>(padding, 0)};
  result.samples.insert(result.samples.end(), audio.samples.begin(), audio.samples.end());
  result.samples.resize(result.samples.size() + padding, 0);
  return result;
}

// espeak-ng's rendering of the transcript, ready to warp: its audio (padded, at kFeatureRateHz), its
// phones (stops from their closures), each phone's start before that move (a stop's burst), its frames.
struct Rendering {
  PcmAudio audio;
  LabeledUtterance phones;
  std::vector<std::int64_t> bursts_us;
  FeatureFrames frames;
};

Rendering prepared_rendering(PcmAudio audio, LabeledUtterance phones) {
  Rendering rendering{std::move(audio), std::move(phones), {}, {}};
  rendering.bursts_us = move_stop_starts_to_closures(rendering.audio, rendering.phones);
  rendering.frames = mfcc_features(rendering.audio);
  return rendering;
}

// The frames quieter than the loudest by more than kSpeechRangeDb.
std::vector<bool> pause_frames(const FeatureFrames& frames) {
  std::vector<bool> quiet(frames.size(), false);
  if (frames.level_db.size() != frames.size() || frames.level_db.empty()) return quiet;
  const double loudest = *std::max_element(frames.level_db.begin(), frames.level_db.end());
  for (std::size_t k = 0; k < quiet.size(); ++k) quiet[k] = frames.level_db[k] < loudest - kSpeechRangeDb;
  return quiet;
}

// `audio` (kFeatureRateHz) and `phones` (espeak-ng's, stops from their bursts) with each pause of
// `pauses` put in as silence at the start of its phone in `moved` (the same phones, stops from their
// closures): a stop's closure then follows the pause, the pause's interval ends at its burst. Each of
// `cuts` is cut from the middle of its pause in `moved`, the pause's intervals shortened.
std::pair<PcmAudio, LabeledUtterance> with_pauses(const PcmAudio& audio, const LabeledUtterance& phones,
                                                  const LabeledUtterance& moved, std::vector<MissingPause> pauses,
                                                  const std::vector<ExtraPause>& cuts) {
  // Edits from the last phone back, so that each finds the times and indices before it unchanged.
  struct Edit {
    std::size_t phone;
    const MissingPause* pause;
    const ExtraPause* cut;
  };
  std::vector<Edit> edits;
  edits.reserve(pauses.size() + cuts.size());
  for (const MissingPause& pause : pauses) edits.push_back({pause.phone, &pause, nullptr});
  for (const ExtraPause& cut : cuts) {
    const bool crossed = std::any_of(pauses.begin(), pauses.end(), [&](const MissingPause& pause) {
      return pause.phone >= cut.first_phone && pause.phone <= cut.last_phone + 1;
    });
    if (!crossed) edits.push_back({cut.first_phone, nullptr, &cut});
  }
  std::sort(edits.begin(), edits.end(), [](const Edit& a, const Edit& b) { return a.phone > b.phone; });
  PcmAudio result_audio = audio;
  LabeledUtterance result_phones = phones;
  std::vector<LabeledInterval>& intervals = result_phones.intervals;
  const auto sample_at = [](std::int64_t us) { return static_cast<std::size_t>(us * kFeatureRateHz / 1'000'000); };
  std::size_t previous_phone = intervals.size();
  for (const Edit& edit : edits) {
    if (edit.cut != nullptr) {
      const ExtraPause& cut = *edit.cut;
      const std::int64_t from_us = moved.intervals[cut.first_phone].start_us;
      const std::int64_t to_us = moved.intervals[cut.last_phone].end_us;
      const std::size_t begin = sample_at((from_us + to_us - cut.duration_us) / 2);
      const std::size_t end = std::min(result_audio.samples.size(), begin + sample_at(cut.duration_us));
      const std::int64_t cut_begin_us = static_cast<std::int64_t>(begin) * 1'000'000 / kFeatureRateHz;
      const std::int64_t shift_us = static_cast<std::int64_t>(end - begin) * 1'000'000 / kFeatureRateHz;
      result_audio.samples.erase(result_audio.samples.begin() + static_cast<std::ptrdiff_t>(begin),
                                 result_audio.samples.begin() + static_cast<std::ptrdiff_t>(end));
      const auto moved_time = [&](std::int64_t t) {
        return t <= cut_begin_us ? t : std::max(cut_begin_us, t - shift_us);
      };
      for (std::size_t k = cut.first_phone; k < intervals.size(); ++k) {
        intervals[k].start_us = moved_time(intervals[k].start_us);
        intervals[k].end_us = moved_time(intervals[k].end_us);
      }
      // A pause of the run left empty goes (the run keeps at least a frame's length).
      for (std::size_t k = cut.last_phone + 1; k-- > cut.first_phone;) {
        if (intervals[k].end_us <= intervals[k].start_us)
          intervals.erase(intervals.begin() + static_cast<std::ptrdiff_t>(k));
      }
      continue;
    }
    const MissingPause& pause = *edit.pause;
    if (pause.phone == previous_phone) continue;
    previous_phone = pause.phone;
    const std::int64_t at_us = moved.intervals[pause.phone].start_us;
    const auto at_sample = sample_at(at_us);
    const auto samples = sample_at(pause.duration_us);
    result_audio.samples.insert(result_audio.samples.begin() + static_cast<std::ptrdiff_t>(at_sample), samples, 0);
    const std::int64_t shift_us = static_cast<std::int64_t>(samples) * 1'000'000 / kFeatureRateHz;
    for (std::size_t k = pause.phone; k < intervals.size(); ++k) {
      intervals[k].start_us += shift_us;
      intervals[k].end_us += shift_us;
    }
    if (intervals[pause.phone].label.empty()) {  // a pause of espeak-ng's own, lengthened
      intervals[pause.phone].start_us = at_us;
    } else if (intervals[pause.phone - 1].label.empty()) {
      intervals[pause.phone - 1].end_us = intervals[pause.phone].start_us;
    } else {
      intervals[pause.phone - 1].end_us = at_us;
      intervals.insert(intervals.begin() + static_cast<std::ptrdiff_t>(pause.phone),
                       LabeledInterval{"", at_us, intervals[pause.phone].start_us, intervals[pause.phone].line});
    }
  }
  return {std::move(result_audio), std::move(result_phones)};
}

}  // namespace

void start_bilabial_nasals_at_murmur(std::vector<std::int64_t>& bounds, const std::vector<LabeledInterval>& phones,
                                     const std::vector<double>& level_db) {
  const auto size = static_cast<std::int64_t>(level_db.size());
  for (std::size_t k = 1; k + 1 < phones.size(); ++k) {
    if (lip_phone_for_refiner(phones[k].label) != "M" || !is_vowel(phones[k - 1].label)) continue;
    const std::int64_t vowel_ms = bounds[k - 1] / 1000, start_ms = bounds[k] / 1000;
    const std::int64_t inside_ms = start_ms + kMurmurInVowelUs / 1000;
    const std::int64_t last_ms = std::min({bounds[k + 1] / 1000 - 5, start_ms + kMurmurSearchUs / 1000, size - 1});
    if (start_ms < 10 || inside_ms >= last_ms) continue;
    const auto from = level_db.begin();
    const double loudest_db = *std::max_element(from + vowel_ms, from + inside_ms + 1);
    if (level_db[start_ms] < loudest_db - kMurmurInVowelDb ||
        *std::min_element(from + start_ms, from + inside_ms + 1) < level_db[start_ms] - kMurmurSteadyDb) {
      continue;
    }
    std::int64_t fallen_ms = inside_ms;
    while (fallen_ms <= last_ms && level_db[fallen_ms] > loudest_db - kMurmurFallDb) ++fallen_ms;
    if (fallen_ms > last_ms) continue;
    std::int64_t best_ms = fallen_ms;
    double best_fall_db = -1e9;
    for (std::int64_t t = std::max(fallen_ms - 10, inside_ms); t <= std::min(fallen_ms + 10, last_ms); ++t) {
      if (const double fall = level_db[t - 10] - level_db[t]; fall > best_fall_db) {
        best_fall_db = fall;
        best_ms = t;
      }
    }
    bounds[k] = std::min(best_ms * 1000, bounds[k + 1] - kMinPhoneUs);
  }
}

std::pair<std::size_t, std::size_t> speech_frames(const FeatureFrames& frames) {
  if (frames.level_db.empty()) return {0, 0};
  const double loudest = *std::max_element(frames.level_db.begin(), frames.level_db.end());
  std::size_t first = 0, last = frames.level_db.size() - 1;
  while (first < last && frames.level_db[first] < loudest - kSpeechRangeDb) ++first;
  while (last > first && frames.level_db[last] < loudest - kSpeechRangeDb) --last;
  return {first, last};
}

std::vector<MissingPause> missing_pauses(const WarpPath& path, const FeatureFrames& rendering,
                                         const std::vector<LabeledInterval>& phones, const FeatureFrames& recording) {
  std::vector<MissingPause> missing;
  const std::vector<bool> quiet = pause_frames(recording), rendering_quiet = pause_frames(rendering);
  const auto [speech_first, speech_last] = speech_frames(recording);
  for (std::size_t c0 = speech_first; c0 <= speech_last; ++c0) {
    if (!quiet[c0]) continue;
    std::size_t c1 = c0;
    while (c1 + 1 <= speech_last && quiet[c1 + 1]) ++c1;
    const std::size_t frames = c1 - c0 + 1;
    const std::size_t first = c0;
    c0 = c1;
    if (static_cast<std::int64_t>(frames) * kFeatureHopUs < kLeastPauseUs) continue;
    // The rendering's frames matched to the pause: how many are quiet, and which takes the most of it.
    std::size_t matched_quiet = 0, widest_row = 0, widest_columns = 0;
    for (std::size_t i = 0; i < path.first.size() && i < rendering_quiet.size(); ++i) {
      if (path.last[i] < first || path.first[i] > c1) continue;
      if (rendering_quiet[i]) ++matched_quiet;
      const std::size_t columns = std::min(path.last[i], c1) - std::max(path.first[i], first) + 1;
      if (columns > widest_columns) {
        widest_columns = columns;
        widest_row = i;
      }
    }
    if (matched_quiet >= frames) continue;
    const std::int64_t duration_us = static_cast<std::int64_t>(frames - matched_quiet) * kFeatureHopUs;
    if (duration_us < kLeastMissingPauseUs) continue;
    // The pause goes where the rendering's phone boundary nearest to that frame is.
    const std::int64_t widest_us = feature_frame_centre_us(widest_row);
    std::size_t best = 0;
    std::int64_t best_distance_us = std::numeric_limits<std::int64_t>::max();
    for (std::size_t k = 1; k < phones.size(); ++k) {
      const std::int64_t distance_us = std::abs(phones[k].start_us - widest_us);
      if (distance_us < best_distance_us) {
        best_distance_us = distance_us;
        best = k;
      }
    }
    if (best > 0) missing.push_back({best, duration_us});
  }
  return missing;
}

std::vector<ExtraPause> extra_pauses(const WarpPath& path, const FeatureFrames& rendering,
                                     const std::vector<LabeledInterval>& phones, const FeatureFrames& recording) {
  std::vector<ExtraPause> extra;
  const std::vector<bool> quiet = pause_frames(recording), rendering_quiet = pause_frames(rendering);
  // The recording's frames in a pause of its own: kLeastPauseUs or more at pause level, inside its
  // speech (a stop's closure is shorter).
  std::vector<bool> in_pause(quiet.size(), false);
  const auto [speech_first, speech_last] = speech_frames(recording);
  for (std::size_t c0 = speech_first; c0 <= speech_last && c0 < quiet.size(); ++c0) {
    if (!quiet[c0]) continue;
    std::size_t c1 = c0;
    while (c1 + 1 <= speech_last && quiet[c1 + 1]) ++c1;
    if (static_cast<std::int64_t>(c1 - c0 + 1) * kFeatureHopUs >= kLeastPauseUs) {
      for (std::size_t c = c0; c <= c1; ++c) in_pause[c] = true;
    }
    c0 = c1;
  }
  for (std::size_t k = 1; k + 1 < phones.size(); ++k) {
    if (!phones[k].label.empty()) continue;
    std::size_t last = k;
    while (last + 2 < phones.size() && phones[last + 1].label.empty()) ++last;
    const std::size_t first = k;
    k = last;
    if (phones[first - 1].label.empty() || phones[last + 1].label.empty()) continue;  // the padding's
    // The rendering's rows in the pause (centres inside it), their pause-level ones, and the
    // recording's pause frames matched to them.
    std::size_t quiet_rows = 0, row_begin = path.first.size(), row_end = 0;
    for (std::size_t i = 0; i < path.first.size() && i < rendering_quiet.size(); ++i) {
      const std::int64_t centre_us = feature_frame_centre_us(i);
      if (centre_us < phones[first].start_us || centre_us >= phones[last].end_us) continue;
      row_begin = std::min(row_begin, i);
      row_end = i + 1;
      if (rendering_quiet[i]) ++quiet_rows;
    }
    if (row_end <= row_begin) continue;
    std::size_t matched = 0;
    for (std::size_t c = path.first[row_begin]; c <= path.last[row_end - 1] && c < in_pause.size(); ++c) {
      if (in_pause[c]) ++matched;
    }
    if (matched >= quiet_rows) continue;
    const std::int64_t length_us = phones[last].end_us - phones[first].start_us;
    const std::int64_t duration_us =
        std::min(static_cast<std::int64_t>(quiet_rows - matched) * kFeatureHopUs, length_us - kFeatureHopUs);
    if (duration_us >= kLeastExtraPauseUs) extra.push_back({first, last, duration_us});
  }
  return extra;
}

WarpPath warp(const FeatureFrames& a, const FeatureFrames& b, std::size_t band_frames,
              std::pair<std::size_t, std::size_t> a_speech, std::pair<std::size_t, std::size_t> b_speech,
              const StretchCost& stretch) {
  const std::size_t rows = a.size(), columns = b.size();
  WarpPath path;
  if (rows == 0 || columns == 0) return path;
  const std::size_t corner_rows[4] = {0, a_speech.first, a_speech.second, rows - 1};
  const std::size_t corner_columns[4] = {0, b_speech.first, b_speech.second, columns - 1};

  // The band: columns [low[i], high[i]] of row i, each row reachable from the one above.
  std::vector<std::size_t> low(rows), high(rows);
  for (std::size_t i = 0; i < rows; ++i) {
    const double centre = centre_column(i, corner_rows, corner_columns);
    low[i] = static_cast<std::size_t>(std::max(0.0, std::floor(centre - static_cast<double>(band_frames))));
    high[i] = static_cast<std::size_t>(
        std::min(static_cast<double>(columns - 1), std::ceil(centre + static_cast<double>(band_frames))));
  }
  low[0] = 0;
  high[rows - 1] = columns - 1;
  for (std::size_t i = 1; i < rows; ++i) low[i] = std::max(low[i], low[i - 1]);
  for (std::size_t i = rows - 1; i-- > 0;) {
    high[i] = std::min(high[i], high[i + 1]);
    if (low[i + 1] > 0) high[i] = std::max(high[i], low[i + 1] - 1);
  }

  std::vector<std::size_t> offset(rows + 1, 0);
  for (std::size_t i = 0; i < rows; ++i) offset[i + 1] = offset[i] + (high[i] - low[i] + 1);
  std::vector<std::uint8_t> steps(offset[rows]);
  constexpr double kUnreachable = std::numeric_limits<double>::infinity();
  std::vector<double> previous(columns, kUnreachable), current(columns, kUnreachable);
  // The run of → or ↓ steps that the cheapest way into each cell ends with: +n after n ↓ steps (b's
  // frame j matched to n + 1 frames of a), −n after n → steps, 0 after ↘. A cell keeps only the run of
  // its cheapest way in, not one cost per run length (an approximation that keeps the warp's time and
  // memory).
  std::vector<std::int32_t> previous_run(columns, 0), current_run(columns, 0);
  const std::vector<bool> a_quiet = pause_frames(a), b_quiet = pause_frames(b);
  const auto free_frames = static_cast<std::int32_t>(stretch.free_frames);
  for (std::size_t i = 0; i < rows; ++i) {
    for (std::size_t j = low[i]; j <= high[i]; ++j) {
      const double distance = frame_distance(a, i, b, j);
      // Runs over pause-level frames are free: pauses and closures differ in length between speakers.
      const double run_cost = a_quiet[i] || b_quiet[j] ? 0.0 : stretch.cost;
      double best = kUnreachable;
      std::uint8_t step = kDiagonal;
      std::int32_t run = 0;
      if (i == 0 && j == 0) best = distance;
      if (i > 0 && j > 0 && j - 1 >= low[i - 1] && j - 1 <= high[i - 1] && previous[j - 1] + 2 * distance < best) {
        best = previous[j - 1] + 2 * distance;
      }
      if (i > 0 && j >= low[i - 1] && j <= high[i - 1]) {
        const std::int32_t down_run = std::max(previous_run[j], 0) + 1;
        const bool stretched = down_run > free_frames;
        if (const double cost = previous[j] + distance + (stretched ? run_cost : 0.0); cost < best) {
          best = cost;
          step = kDown | (stretched && run_cost > 0 ? kStretched : 0);
          run = down_run;
        }
      }
      if (j > low[i]) {
        const std::int32_t right_run = std::max(-current_run[j - 1], 0) + 1;
        const bool stretched = right_run > free_frames;
        if (const double cost = current[j - 1] + distance + (stretched ? run_cost : 0.0); cost < best) {
          best = cost;
          step = kRight | (stretched && run_cost > 0 ? kStretched : 0);
          run = -right_run;
        }
      }
      current[j] = best;
      current_run[j] = run;
      steps[offset[i] + (j - low[i])] = step;
    }
    std::swap(previous, current);
    std::swap(previous_run, current_run);
  }
  const double total_cost = previous[columns - 1];
  // The distance of unrelated frames: every frame of a against b's frames at a fixed stride.
  double sum = 0.0;
  std::size_t pairs = 0;
  const std::size_t stride = std::max<std::size_t>(1, columns / 64);
  for (std::size_t i = 0; i < rows; ++i) {
    for (std::size_t j = i % stride; j < columns; j += stride, ++pairs) sum += frame_distance(a, i, b, j);
  }
  path.unrelated_distance = sum / static_cast<double>(pairs);

  path.first.assign(rows, 0);
  path.last.assign(rows, 0);
  std::size_t i = rows - 1, j = columns - 1;
  path.last[i] = j;
  path.first[i] = j;
  double stretch_paid = 0.0;  // what the path paid for its runs, left out of its mean distance
  while (i > 0 || j > 0) {
    const std::uint8_t stored = steps[offset[i] + (j - low[i])];
    if ((stored & kStretched) != 0) stretch_paid += stretch.cost;
    const auto step = static_cast<Step>(stored & ~kStretched);
    if (step == kRight) {
      --j;
    } else {
      if (step == kDiagonal) --j;
      --i;
      path.last[i] = j;
    }
    path.first[i] = j;
  }
  path.mean_distance = (total_cost - stretch_paid) / static_cast<double>(rows + columns);
  return path;
}

std::int64_t carry_time_us(const WarpPath& path, std::int64_t a_us) {
  const std::size_t rows = path.first.size();
  if (rows == 0) return a_us;
  const double position = static_cast<double>(a_us - feature_frame_centre_us(0)) / kFeatureHopUs;
  if (position <= 0)
    return std::max<std::int64_t>(0, feature_frame_centre_us(path.first[0]) + (a_us - feature_frame_centre_us(0)));
  if (position >= static_cast<double>(rows - 1)) {
    return feature_frame_centre_us(path.last[rows - 1]) + (a_us - feature_frame_centre_us(rows - 1));
  }
  const auto row = static_cast<std::size_t>(std::floor(position));  // between rows `row` and `row + 1`
  const double fraction = position - static_cast<double>(row);
  const double from = static_cast<double>(path.last[row]);
  const double to = static_cast<double>(path.first[row + 1]);
  const double column = from + fraction * (to - from);
  return feature_frame_centre_us(0) + static_cast<std::int64_t>(std::llround(column * kFeatureHopUs));
}

Alignment align_speech_to_synthesis(const PcmAudio& input, std::string_view source_view,
                                    const DtwAlignmentOptions& options) {
  const std::string source(source_view);
  const std::string& voice = options.synthesis.voice;
  if (!has_word_character(options.transcript)) {
    throw InputError(source, 0, "the transcript is empty: alignment with --voice " + voice + " needs the words spoken");
  }
  detail::check_alignable_audio(input, source, options.max_duration_s, "alignment");

  Synthesis synthesis;
  try {
    synthesis = synthesize(options.transcript, options.synthesis);
  } catch (const InputError& error) {
    throw InputError(source, 0, "cannot speak the transcript with espeak-ng voice '" + voice + "': " + error.message());
  }
  if (synthesis.phonemes.intervals.empty()) {
    throw InputError(source, 0, "espeak-ng voice '" + voice + "' spoke no phonemes for the transcript");
  }
  char text[400];
  const double duration_s = double(input.samples.size()) / input.sample_rate_hz;
  const double synthesis_s = double(synthesis.audio.samples.size()) / synthesis.audio.sample_rate_hz;
  if (duration_s > kMostDurationRatio * synthesis_s || synthesis_s > kMostDurationRatio * duration_s) {
    std::snprintf(text, sizeof text,
                  "the recording (%.1f s) cannot be the transcript: espeak-ng voice '%s' speaks it in %.1f s "
                  "(more than %.0f times longer or shorter)",
                  duration_s, voice.c_str(), synthesis_s, kMostDurationRatio);
    throw InputError(source, 0, text);
  }

  Alignment result;
  result.phones.source = source;
  result.phones.phone_set = phone_set_for_voice(voice);
  if (input.sample_rate_hz != kFeatureRateHz) {
    result.notes.push_back("resampled from " + std::to_string(input.sample_rate_hz) + " Hz to " +
                           std::to_string(kFeatureRateHz) + " Hz for the alignment");
  }
  const PcmAudio recording = resample(input, kFeatureRateHz);
  const PcmAudio spoken = padded(resample(synthesis.audio, kFeatureRateHz));
  LabeledUtterance synthesis_phones = synthesis.phonemes;
  for (LabeledInterval& interval : synthesis_phones.intervals) {
    interval.start_us += kSynthesisPaddingUs;
    interval.end_us += kSynthesisPaddingUs;
  }
  // The padding is pause: its own intervals (merged with a pause espeak-ng begins or ends with).
  std::vector<LabeledInterval>& padded_phones = synthesis_phones.intervals;
  if (padded_phones.front().label.empty()) {
    padded_phones.front().start_us = 0;
  } else {
    padded_phones.insert(padded_phones.begin(), LabeledInterval{"", 0, kSynthesisPaddingUs, 0});
  }
  const std::int64_t spoken_end_us = spoken.duration_us();
  if (padded_phones.back().label.empty()) {
    padded_phones.back().end_us = spoken_end_us;
  } else {
    padded_phones.push_back(LabeledInterval{"", padded_phones.back().end_us, spoken_end_us, 0});
  }
  const FeatureFrames recording_frames = mfcc_features(recording);
  const auto band_frames = static_cast<std::size_t>(std::max(1.0, options.band_s * 1e6 / kFeatureHopUs));
  const auto warp_to_recording = [&](const Rendering& rendering) {
    return warp(rendering.frames, recording_frames, band_frames, speech_frames(rendering.frames),
                speech_frames(recording_frames), options.stretch);
  };
  Rendering rendering = prepared_rendering(spoken, synthesis_phones);
  WarpPath path = warp_to_recording(rendering);
  const std::vector<MissingPause> pauses =
      missing_pauses(path, rendering.frames, rendering.phones.intervals, recording_frames);
  const std::vector<ExtraPause> cuts =
      extra_pauses(path, rendering.frames, rendering.phones.intervals, recording_frames);
  if (!pauses.empty() || !cuts.empty()) {
    auto [paused_audio, paused_phones] = with_pauses(spoken, synthesis_phones, rendering.phones, pauses, cuts);
    Rendering paused = prepared_rendering(std::move(paused_audio), std::move(paused_phones));
    WarpPath paused_path = warp_to_recording(paused);
    if (paused_path.mean_distance <= path.mean_distance) {
      rendering = std::move(paused);
      path = std::move(paused_path);
    }
  }
  if (path.mean_distance > options.max_distance_ratio * path.unrelated_distance) {
    std::snprintf(text, sizeof text,
                  "the recording does not match the transcript as espeak-ng voice '%s' speaks it (the best warp's "
                  "frames are %.0f %% as far apart as unrelated frames, at most %.0f %% accepted): is it speech, "
                  "saying the transcript, in that voice's language?",
                  voice.c_str(), 100.0 * path.mean_distance / path.unrelated_distance,
                  100.0 * options.max_distance_ratio);
    throw InputError(source, 0, text);
  }
  std::snprintf(text, sizeof text,
                "aligned against espeak-ng voice '%s' (mean distance along the warp %.2f, %.0f %% of unrelated "
                "frames)",
                voice.c_str(), path.mean_distance, 100.0 * path.mean_distance / path.unrelated_distance);
  result.notes.push_back(text);

  const std::vector<LabeledInterval>& spoken_phones = rendering.phones.intervals;
  const std::size_t count = spoken_phones.size();
  const std::int64_t end_us = input.duration_us();
  std::vector<std::int64_t> bounds =
      carried_bounds(path, spoken_phones, rendering.bursts_us, end_us, pause_frames(recording_frames), recording);
  start_bilabial_nasals_at_murmur(bounds, spoken_phones, formant_band_levels_db(recording, 10'000, 1'000));
  for (std::size_t k = 0; k < count; ++k) {
    LabeledInterval interval = spoken_phones[k];
    interval.start_us = bounds[k];
    interval.end_us = bounds[k + 1];
    interval.line = static_cast<int>(k + 1);
    if (interval.end_us > interval.start_us) result.phones.intervals.push_back(std::move(interval));
  }
  if (result.phones.intervals.empty()) throw InputError(source, 0, "the audio is too short for the transcript");
  result.phones.intervals.front().start_us = 0;
  result.phones.intervals.back().end_us = end_us;
  if (options.refine_closures) result.refined = refine_lip_phones(recording, result.phones, options.refiner);
  return result;
}

}  // namespace lipsync::speech
