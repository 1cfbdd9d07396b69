// Phonemes from live audio with PocketSphinx's incremental decoding (lipsync/speech/live_recognizer.hpp).
#include "lipsync/speech/live_recognizer.hpp"

#include <pocketsphinx.h>
#include <sphinxbase/cmn.h>
#include <sphinxbase/err.h>
#include <sphinxbase/feat.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <sstream>

#include "lipsync/error.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/audio.hpp"
#include "pocketsphinx_words.hpp"

namespace lipsync::speech {
namespace {

constexpr int kModelRateHz = 16000;
constexpr std::int64_t kFrameSamples = kModelRateHz * detail::kFrameUs / 1'000'000;  // 160
// Voice activity (see the header): a frame is voiced this far over the noise floor and above the
// absolute level. The floor is the quietest frame of the last kFloorWindowFrames (1.5 s): speech
// always dips within that (closures, gaps between words), so the floor under speech is the room's,
// while a steady noise becomes the floor itself within 1.5 s of its start.
constexpr double kVoiceOverFloorDb = 15.0;
constexpr double kQuietestVoiceDbfs = -55.0;
constexpr std::size_t kFloorWindowFrames = 150;
constexpr double kDigitalSilenceDbfs = -120.0;
// Audio before the first final phone still open to the closure refiner, so that a boundary just
// behind the final ones is refined with the signal on both sides of it.
constexpr std::int64_t kRefinerContextUs = 300'000;
// Silence after the last voiced frame: once it lasts this long it is no stop's closure, and the
// phones the decoder stretched over it end this long after the voice did (the grammar of a
// transcript has no pause between words; the phone loop's silence comes late).
constexpr std::int64_t kTrailingSilenceUs = 100'000;
constexpr std::int64_t kVoiceDecayUs = 30'000;
// A grammar whose hypothesis has come within this many words of its end is decoded again when
// words have come since: the partial hypothesis trails the speech by a word or so.
constexpr std::int64_t kWordsLeftForAnotherDecode = 3;
// The most audio decoded at once (a push of seconds, as fast as a client sends, is decoded in steps).
constexpr std::size_t kDecodeStepSamples = kModelRateHz / 10;

bool is_file(const std::string& path) {
  struct stat info {};
  return ::stat(path.c_str(), &info) == 0 && S_ISREG(info.st_mode);
}

double level_dbfs(std::span<const std::int16_t> frame) {
  double energy = 0;
  for (const std::int16_t s : frame) energy += double(s) * double(s);
  const double rms = std::sqrt(energy / double(frame.size())) / 32768.0;
  return rms > 0 ? std::max(kDigitalSilenceDbfs, 20.0 * std::log10(rms)) : kDigitalSilenceDbfs;
}

/// "12.345 s".
std::string time_text(std::int64_t us) {
  char text[32];
  std::snprintf(text, sizeof text, "%lld.%03lld s", static_cast<long long>(us / 1'000'000),
                static_cast<long long>(us / 1000 % 1000));
  return text;
}

std::string beam_text(double beam) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", beam);
  return text;
}

/// Forced alignment's beams (all but open) and language weight, as the offline aligner's.
constexpr double kForcedBeam = 1e-200;
constexpr double kForcedWeight = 6.5;
/// The phone loop's language weight (the phonetic LM's, as the offline aligner runs it).
constexpr double kPhoneLoopWeight = 2.0;

/// The beams and language weight that the next search built on `config` reads.
void set_search_tuning(cmd_ln_t* config, double beam, double weight) {
  for (const char* name : {"-beam", "-pbeam", "-wbeam"}) cmd_ln_set_float_r(config, name, beam);
  cmd_ln_set_float_r(config, "-lw", weight);
}

}  // namespace

class LiveDecoder {
 public:
  explicit LiveDecoder(const LiveRecognitionOptions& options) : made_for(options) {}
  ~LiveDecoder() {
    if (ps != nullptr) ps_free(ps);
  }
  LiveDecoder(const LiveDecoder&) = delete;
  LiveDecoder& operator=(const LiveDecoder&) = delete;

  void remember_means() {
    feat_t* feat = ps_get_feat(ps);
    initial_means.assign(static_cast<std::size_t>(feat_cepsize(feat)), 0);
    cmn_live_get(feat->cmn_struct, initial_means.data());
  }
  void restore_means() { cmn_live_set(ps_get_feat(ps)->cmn_struct, initial_means.data()); }

  /// The options it was loaded for (same_live_decoder).
  LiveRecognitionOptions made_for;
  ps_decoder_t* ps = nullptr;
  /// The stream's rate to the model's, set by the recogniser that takes it.
  std::optional<StreamingResampler> resampler;
  // The cepstral means the model starts with. PocketSphinx carries its running means from one
  // utterance to the next, and the digital silence a synthesiser leaves at an utterance's end drags
  // them far from speech: the next utterance then decodes to silence. Each utterance starts from
  // these, as the first does, so that each is decoded as if it were the stream's first.
  std::vector<mfcc_t> initial_means;
  // Two grammar names, used in turn: replacing the search in use would free it under the decoder.
  int grammar_turn = 0;
  bool phone_loop_built = false;
};

void LiveDecoderDeleter::operator()(LiveDecoder* decoder) const { delete decoder; }

namespace {

/// Builds the phone loop's search on `decoder` (about a quarter of a second). A search reads its
/// beams and language weight from the decoder's configuration when it is built. With a transcript
/// the configuration is forced alignment's (beams all but open, weight 6.5): a phone loop built on
/// it searches every path, about five times slower than the speech (the speech after the
/// transcript's last word stalled the stream for seconds). It is built with the phone loop's own,
/// and the configuration put back for the grammars built later.
void build_phone_loop(LiveDecoder& decoder, const std::string& source) {
  const LiveRecognitionOptions& options = decoder.made_for;
  const bool forced = options.transcript.has_value();
  cmd_ln_t* config = ps_get_config(decoder.ps);
  if (forced) set_search_tuning(config, options.phone_beam, kPhoneLoopWeight);
  const std::string phone_lm = options.model_dir + "/en-us-phone.lm.bin";
  const int failed = ps_set_allphone_file(decoder.ps, "phones", phone_lm.c_str());
  if (forced) set_search_tuning(config, kForcedBeam, kForcedWeight);
  if (failed != 0) throw InputError(source, 0, "cannot load the phonetic language model " + phone_lm);
  decoder.phone_loop_built = true;
}

}  // namespace

bool same_live_decoder(const LiveRecognitionOptions& prepared_for, const LiveRecognitionOptions& options) {
  return prepared_for.transcript.has_value() == options.transcript.has_value() &&
         prepared_for.model_dir == options.model_dir && prepared_for.phone_beam == options.phone_beam &&
         prepared_for.phone_top_gaussians == options.phone_top_gaussians;
}

PreparedLiveDecoder prepare_live_decoder(const LiveRecognitionOptions& options, const std::string& source) {
  const std::string hmm = options.model_dir + "/en-us";
  const std::string dict = options.model_dir + "/cmudict-en-us.dict";
  const std::string phone_lm = options.model_dir + "/en-us-phone.lm.bin";
  for (const std::string& path : {hmm + "/mdef", dict, phone_lm}) {
    if (!is_file(path)) {
      throw InputError(
          source, 0,
          "the PocketSphinx model is missing (" + path + "; install it with 'apt-get install pocketsphinx-en-us')");
    }
  }
  err_set_logfp(nullptr);  // PocketSphinx logs to stderr by default
  // The phone loop as the offline aligner runs it (the phonetic LM at weight 2) with narrower beams;
  // the transcript's grammar as the offline forced alignment runs it (beams all but open, weight 6.5).
  const bool forced = options.transcript.has_value();
  const std::string beam = beam_text(forced ? kForcedBeam : options.phone_beam);
  const std::string weight = beam_text(forced ? kForcedWeight : kPhoneLoopWeight);
  cmd_ln_t* config =
      cmd_ln_init(nullptr, ps_args(), TRUE, "-hmm", hmm.c_str(), "-dict", dict.c_str(), "-samprate", "16000",
                  "-remove_silence", "no", "-beam", beam.c_str(), "-pbeam", beam.c_str(), "-wbeam", beam.c_str(),
                  "-bestpath", "no", "-fsgusefiller", "no", "-lw", weight.c_str(), "-topn",
                  forced ? "4" : std::to_string(options.phone_top_gaussians).c_str(), nullptr);
  if (config == nullptr) throw InputError(source, 0, "cannot configure PocketSphinx");
  PreparedLiveDecoder decoder(new LiveDecoder(options));
  decoder->ps = ps_init(config);
  cmd_ln_free_r(config);
  if (decoder->ps == nullptr)
    throw InputError(source, 0, "cannot load the PocketSphinx model from " + options.model_dir);
  // The phone loop costs about a quarter of a second to build: with a transcript it is built only
  // if the speech outlasts the transcript's words.
  if (forced) {
    detail::add_word(decoder->ps, detail::kPauseWord, "SIL");
  } else {
    build_phone_loop(*decoder, source);
  }
  decoder->remember_means();
  return decoder;
}

LiveRecognizer::LiveRecognizer(const LiveRecognitionOptions& options, std::string source, PreparedLiveDecoder prepared)
    : options_(options), source_(std::move(source)) {
  if (options_.sample_rate_hz < 8000 || options_.sample_rate_hz > 48000) {
    throw InputError(
        source_, 0,
        "sample rate " + std::to_string(options_.sample_rate_hz) + " Hz: live audio takes 8000 to 48000 Hz");
  }
  has_transcript_ = options_.transcript.has_value();
  decoder_ = prepared && same_live_decoder(prepared->made_for, options_) ? std::move(prepared)
                                                                         : prepare_live_decoder(options_, source_);
  decoder_->resampler.emplace(options_.sample_rate_hz, kModelRateHz);
  if (has_transcript_) add_words(*options_.transcript);
  if (!has_transcript_) ps_set_search(decoder_->ps, "phones");
  frame_.reserve(kFrameSamples);
}

LiveRecognizer::~LiveRecognizer() = default;

void LiveRecognizer::add_words(std::string_view text) {
  for (std::string& word : transcript_words(text)) add_word(std::move(word), -1);
}

void LiveRecognizer::add_timed_words(std::span<const TimedWord> words) {
  std::int64_t previous_us = 0;
  for (auto w = words_.rbegin(); w != words_.rend(); ++w) {
    if (w->start_us >= 0) {
      previous_us = w->start_us;
      break;
    }
  }
  for (const TimedWord& timed : words) {
    const std::vector<std::string> split = transcript_words(timed.text);
    const std::string number = "timed word " + std::to_string(words_end() + 1) + " '" + timed.text + "'";
    if (split.empty()) throw InputError(source_, 0, number + " has no letters or digits");
    if (timed.start_us < previous_us) {
      throw InputError(source_, 0,
                       number + " starts at " + std::to_string(timed.start_us) + " us, before the word before it (" +
                           std::to_string(previous_us) +
                           " us): timed words come in the order they are spoken, on the stream's clock");
    }
    previous_us = timed.start_us;
    // "state-of-the-art" is several dictionary words: the first carries the time.
    for (std::size_t i = 0; i < split.size(); ++i) add_word(split[i], i == 0 ? timed.start_us : -1);
  }
}

void LiveRecognizer::add_word(std::string text, std::int64_t start_us) {
  if (!has_transcript_) {
    throw InputError(source_, 0,
                     "word '" + text +
                         "' given to a stream without a transcript (a stream whose words come later starts "
                         "with an empty transcript)");
  }
  if (detail::pronunciations(decoder_->ps, text).empty()) {
    throw InputError(source_, 0,
                     "transcript word " + std::to_string(words_end() + 1) + " '" + text +
                         "' is not in the pronouncing dictionary (write numbers and abbreviations out as words)");
  }
  words_.push_back({std::move(text), start_us});
}

void LiveRecognizer::use_phone_loop() {
  if (!decoder_->phone_loop_built) build_phone_loop(*decoder_, source_);
  ps_set_search(decoder_->ps, "phones");
}

std::int64_t LiveRecognizer::sample_us(std::int64_t sample) const { return sample * 1'000'000 / kModelRateHz; }

void LiveRecognizer::push(std::span<const std::int16_t> samples) {
  resampled_.clear();
  decoder_->resampler->push(samples, resampled_);
  for (const std::int16_t sample : resampled_) {
    frame_.push_back(sample);
    if (frame_.size() == static_cast<std::size_t>(kFrameSamples)) {
      process_frame(frame_);
      frame_.clear();
      // A long push is decoded in steps, so that the phones and the grammar's words keep up within it.
      if (open_ && decode_queue_.size() >= kDecodeStepSamples) decode_queued();
    }
  }
  if (open_ && !decode_queue_.empty()) decode_queued();
}

void LiveRecognizer::decode_queued() {
  ps_process_raw(decoder_->ps, decode_queue_.data(), decode_queue_.size(), FALSE, FALSE);
  decode_queue_.clear();
  update_phones(false);
  redecode_if_words_ran_out();
}

void LiveRecognizer::finish() {
  resampled_.clear();
  decoder_->resampler->finish(resampled_);
  frame_.insert(frame_.end(), resampled_.begin(), resampled_.end());
  // The last, partial frame is classified as a whole one would be.
  if (!frame_.empty()) process_frame(frame_);
  frame_.clear();
  if (open_) close_utterance();
  // What is left outside utterances (the pre-roll kept for an utterance that never came) is silence.
  if (sample_us(samples_seen_) > final_us_) {
    if (!final_.empty() && final_.back().label.empty()) {
      final_.back().end_us = sample_us(samples_seen_);
    } else {
      final_.push_back({"", final_us_, sample_us(samples_seen_), 0});
    }
    final_us_ = sample_us(samples_seen_);
  }
  pre_roll_.clear();
  guess_.clear();
  heard_us_ = final_us_;
  finished_ = true;
}

void LiveRecognizer::process_frame(std::span<const std::int16_t> frame) {
  const double level = level_dbfs(frame);
  // The floor: the minimum of the window's levels, kept as a deque of (frame, level) whose levels
  // rise from front to back (each level is dropped once a later one is as quiet).
  while (!floor_window_.empty() && floor_window_.back().second >= level) floor_window_.pop_back();
  floor_window_.emplace_back(frames_classified_, level);
  if (floor_window_.front().first + static_cast<std::int64_t>(kFloorWindowFrames) <= frames_classified_) {
    floor_window_.pop_front();
  }
  ++frames_classified_;
  const double noise_floor_db = floor_window_.front().second;
  const bool voiced = level > kQuietestVoiceDbfs && level > noise_floor_db + kVoiceOverFloorDb;
  const auto frame_size = static_cast<std::int64_t>(frame.size());
  if (!open_ && voiced) open_utterance();
  if (!open_) {
    pre_roll_.insert(pre_roll_.end(), frame.begin(), frame.end());
    const auto keep = static_cast<std::size_t>(options_.pre_roll_us * kModelRateHz / 1'000'000);
    if (pre_roll_.size() > keep)
      pre_roll_.erase(pre_roll_.begin(), pre_roll_.end() - static_cast<std::ptrdiff_t>(keep));
    samples_seen_ += frame_size;
    // Silence up to the pre-roll is final: no utterance can reach back before it.
    const std::int64_t silent_until = sample_us(samples_seen_ - static_cast<std::int64_t>(pre_roll_.size()));
    if (silent_until > final_us_) {
      if (!final_.empty() && final_.back().label.empty()) {
        final_.back().end_us = silent_until;
      } else {
        final_.push_back({"", final_us_, silent_until, 0});
      }
      final_us_ = silent_until;
    }
    heard_us_ = sample_us(samples_seen_);
    guess_.clear();
    if (heard_us_ > final_us_) guess_.push_back({"", final_us_, heard_us_, 0});
    return;
  }
  utterance_audio_.insert(utterance_audio_.end(), frame.begin(), frame.end());
  decode_queue_.insert(decode_queue_.end(), frame.begin(), frame.end());
  samples_seen_ += frame_size;
  silent_samples_ = voiced ? 0 : silent_samples_ + frame_size;
  if (voiced) voiced_samples_ += frame_size;
  const std::int64_t length_us = sample_us(static_cast<std::int64_t>(utterance_audio_.size()));
  if (sample_us(silent_samples_) >= options_.end_pause_us || length_us >= options_.max_utterance_us) {
    close_utterance();
  }
}

void LiveRecognizer::open_utterance() {
  utterance_voice_us_ = sample_us(samples_seen_);
  grammar_first_ = first_word_of_utterance();
  start_search();
  open_ = true;
  utterance_first_sample_ = samples_seen_ - static_cast<std::int64_t>(pre_roll_.size());
  utterance_audio_ = pre_roll_;
  decode_queue_ = pre_roll_;
  pre_roll_.clear();
  silent_samples_ = 0;
  voiced_samples_ = 0;
}

std::size_t LiveRecognizer::first_word_of_utterance() const {
  // The words' times, where a TTS gave them, place the utterance in the transcript: its first word
  // is the first to start after the middle of the pause before it (the first utterance's, the
  // first word); a word's onset may be too quiet for the voice detector, and marks are a little off.
  const std::int64_t from_us = utterances_ == 0 ? 0 : (last_voice_end_us_ + utterance_voice_us_) / 2;
  for (std::size_t w = words_base_; w < words_end(); ++w) {
    if (word(w).start_us >= 0 && word(w).start_us >= from_us) return w;
  }
  return std::min(next_word_, words_end());
}

void LiveRecognizer::start_search() {
  ps_decoder_t* ps = decoder_->ps;
  grammar_end_ = std::min(words_end(), grammar_first_ + options_.transcript_window_words);
  max_word_heard_ = -1;

  if (grammar_end_ > grammar_first_) {
    // The next words, each a prefix of the rest: "[pause] [ (w1 [ (w2 [ ... [pause] ]) ]) ]". No pause
    // between two words: the partial hypothesis is the best path ending at the newest frame that
    // has a word exit, and a pause, which may exit at every frame, would win it over the words
    // whenever the voice is far from the model's (espeak-ng's); a pause long enough to matter ends
    // the utterance instead, and a shorter silence after the last voiced frame is cut off the
    // phones (update_phones).
    // Its one-phone words carry their word's place in the grammar (so the dictionary holds at most
    // the window's length of each phone, however long the stream).
    const std::string pause = std::string(detail::kPauseWord);
    std::string tail;
    for (std::size_t w = grammar_end_; w-- > grammar_first_;) {
      std::string alternatives;
      for (const std::string& pronunciation : detail::pronunciations(ps, word(w).text)) {
        if (!alternatives.empty()) alternatives += " |";
        std::istringstream phones(pronunciation);
        for (std::string phone; phones >> phone;) {
          const std::string phone_word = detail::phone_word(phone, w - grammar_first_);
          detail::add_word(ps, phone_word, phone);
          alternatives += " " + phone_word;
        }
      }
      tail = "( (" + alternatives + " )" + (tail.empty() ? " [ " + pause + " ]" : " [ " + tail + " ]") + " )";
    }
    const std::string grammar =
        "#JSGF V1.0;\ngrammar transcript;\npublic <utterance> = [ " + pause + " ] [ " + tail + " ] ;\n";
    const char* name = decoder_->grammar_turn++ % 2 == 0 ? "transcript_a" : "transcript_b";
    if (ps_set_jsgf_string(ps, name, grammar.c_str()) != 0 || ps_set_search(ps, name) != 0) {
      throw InputError(source_, 0, "PocketSphinx rejected the transcript's grammar");
    }
  } else {
    use_phone_loop();
  }
  decoder_->restore_means();
  // A stream of its own per utterance: PocketSphinx numbers an utterance's frames from the start of
  // its stream, and the segments' frames are read as counted from the utterance's first sample.
  ps_start_stream(ps);
  ps_start_utt(ps);
}

void LiveRecognizer::redecode_if_words_ran_out() {
  if (!open_ || !has_transcript_) return;
  const bool on_phone_loop = grammar_end_ == grammar_first_;
  if (!on_phone_loop && max_word_heard_ + kWordsLeftForAnotherDecode < static_cast<std::int64_t>(grammar_end_)) {
    return;  // words enough left
  }
  const std::size_t first = on_phone_loop ? first_word_of_utterance() : grammar_first_;
  if (std::min(words_end(), first + options_.transcript_window_words) <= grammar_end_) return;  // none came
  ps_end_utt(decoder_->ps);
  ++redecodes_;
  grammar_first_ = first;
  start_search();
  decode_queue_.clear();
  ps_process_raw(decoder_->ps, utterance_audio_.data(), utterance_audio_.size(), FALSE, FALSE);
  update_phones(false);
}

void LiveRecognizer::note_how_the_transcript_went() {
  const std::string at = "the speech at " + time_text(utterance_voice_us_);
  if (grammar_end_ == grammar_first_) {
    if (!said_words_ran_out_) {
      notes_.push_back(at + " comes after the transcript's last word: its phones are recognised without it");
      said_words_ran_out_ = true;  // once for a run of such utterances
    }
    return;
  }
  said_words_ran_out_ = false;
  if (max_word_heard_ < 0 && sample_us(voiced_samples_) >= options_.mismatch_voiced_us) {
    notes_.push_back(at + " (" + std::to_string(sample_us(voiced_samples_) / 1000) +
                     " ms of voice) holds none of the transcript's words from word " +
                     std::to_string(grammar_first_ + 1) + " '" + word(grammar_first_).text +
                     "' on: it does not follow the transcript there");
  }
}

void LiveRecognizer::close_utterance() {
  if (!decode_queue_.empty()) {
    ps_process_raw(decoder_->ps, decode_queue_.data(), decode_queue_.size(), FALSE, FALSE);
    decode_queue_.clear();
  }
  ps_end_utt(decoder_->ps);
  update_phones(true);
  last_voice_end_us_ = sample_us(samples_seen_ - silent_samples_);
  if (has_transcript_) note_how_the_transcript_went();
  if (max_word_heard_ >= 0) next_word_ = static_cast<std::size_t>(max_word_heard_) + 1;
  // Words far behind the speech are not needed again.
  while (words_base_ + options_.transcript_window_words < next_word_ && !words_.empty()) {
    words_.pop_front();
    ++words_base_;
  }
  open_ = false;
  ++utterances_;
  utterance_audio_.clear();
  silent_samples_ = 0;
}

void LiveRecognizer::update_phones(bool ended) {
  const std::int64_t start_us = sample_us(utterance_first_sample_);
  const std::int64_t end_us = sample_us(samples_seen_);
  heard_us_ =
      ended ? end_us : std::min(end_us, start_us + std::int64_t{ps_get_n_frames(decoder_->ps)} * detail::kFrameUs);
  // The hypothesis as phones on the stream's clock, tiling [start_us, heard_us_).
  std::vector<LabeledInterval> phones;
  for (ps_seg_t* seg = ps_seg_iter(decoder_->ps); seg != nullptr; seg = ps_seg_next(seg)) {
    int first_frame = 0, last_frame = 0;
    ps_seg_frames(seg, &first_frame, &last_frame);
    const std::string_view word = ps_seg_word(seg);
    if (word == "(NULL)") continue;
    const auto [phone, index] = detail::phone_of(word);
    if (index >= 0) max_word_heard_ = std::max(max_word_heard_, static_cast<std::int64_t>(grammar_first_) + index);
    const std::int64_t from =
        first_frame == 0 ? start_us : start_us + first_frame * detail::kFrameUs + detail::kBoundaryOffsetUs;
    const std::int64_t to =
        std::min(heard_us_, start_us + (last_frame + 1) * detail::kFrameUs + detail::kBoundaryOffsetUs);
    const std::int64_t begin = phones.empty() ? start_us : phones.back().end_us;
    if (to <= begin) continue;
    if (from > begin) phones.push_back({"", begin, from, 0});  // a gap in the path is silence
    if (!phones.empty() && phones.back().label.empty() && phone.empty()) {
      phones.back().end_us = to;
    } else {
      phones.push_back({phone, phones.empty() ? start_us : phones.back().end_us, to, 0});
    }
  }
  if (phones.empty() || phones.back().end_us < heard_us_) {
    const std::int64_t begin = phones.empty() ? start_us : phones.back().end_us;
    if (!phones.empty() && phones.back().label.empty()) {
      phones.back().end_us = heard_us_;
    } else {
      phones.push_back({"", begin, heard_us_, 0});
    }
  }

  // A silence heard after the last voiced frame is silence, whatever the decoder stretched over it.
  const std::int64_t silent_us = sample_us(silent_samples_);
  if (silent_us >= kTrailingSilenceUs) {
    const std::int64_t voice_end_us = std::max(start_us, end_us - silent_us + kVoiceDecayUs);
    if (voice_end_us < heard_us_) {
      while (!phones.empty() && phones.back().start_us >= voice_end_us) phones.pop_back();
      if (!phones.empty() && phones.back().label.empty()) {
        phones.back().end_us = heard_us_;
      } else {
        if (!phones.empty()) phones.back().end_us = voice_end_us;
        phones.push_back({"", phones.empty() ? start_us : voice_end_us, heard_us_, 0});
      }
    }
  }

  // The lip phones' boundaries moved to the signal, over the audio from a little before the final ones.
  if (options_.refine_closures) {
    const std::int64_t window_from_us = std::max(start_us, final_us_ - kRefinerContextUs);
    const auto first = std::find_if(phones.begin(), phones.end(),
                                    [&](const LabeledInterval& phone) { return phone.end_us > window_from_us; });
    if (first != phones.end()) {
      const std::int64_t from_us = first->start_us;
      const auto from_sample = static_cast<std::size_t>((from_us - start_us) * kModelRateHz / 1'000'000);
      const auto to_sample = std::min(utterance_audio_.size(),
                                      static_cast<std::size_t>((heard_us_ - start_us) * kModelRateHz / 1'000'000));
      if (to_sample > from_sample) {
        PcmAudio window;
        window.sample_rate_hz = kModelRateHz;
        window.samples.assign(utterance_audio_.begin() + static_cast<std::ptrdiff_t>(from_sample),
                              utterance_audio_.begin() + static_cast<std::ptrdiff_t>(to_sample));
        LabeledUtterance local;
        local.phone_set = "arpabet";
        for (auto it = first; it != phones.end(); ++it) {
          local.intervals.push_back({it->label, it->start_us - from_us, it->end_us - from_us, 0});
        }
        local.intervals.back().end_us = std::max(local.intervals.back().end_us, window.duration_us());
        refine_closures(window, local, options_.refiner);
        auto it = first;
        for (const LabeledInterval& refined : local.intervals) {
          it->start_us = refined.start_us + from_us;
          it->end_us = refined.end_us + from_us;
          ++it;
        }
        phones.back().end_us = heard_us_;
      }
    }
  }

  // What lies after the final phones: the first one clipped to start where they end.
  std::vector<LabeledInterval> after;
  for (const LabeledInterval& phone : phones) {
    if (phone.end_us <= final_us_) continue;
    LabeledInterval clipped = phone;
    clipped.start_us = std::max(clipped.start_us, final_us_);
    if (!after.empty()) clipped.start_us = after.back().end_us;
    if (clipped.end_us > clipped.start_us) after.push_back(std::move(clipped));
  }
  const auto take = [&](const LabeledInterval& phone) {
    if (!final_.empty() && final_.back().label.empty() && phone.label.empty()) {
      final_.back().end_us = phone.end_us;
    } else {
      final_.push_back(phone);
    }
    final_us_ = phone.end_us;
  };
  guess_.clear();
  for (std::size_t i = 0; i < after.size(); ++i) {
    const bool settled = i + 1 < after.size() && after[i].end_us <= heard_us_ - options_.commit_us;
    if (ended || (settled && guess_.empty())) {
      take(after[i]);
    } else {
      guess_.push_back(after[i]);
    }
  }
  if (ended && final_us_ < end_us) take({"", final_us_, end_us, 0});
}

std::vector<LabeledInterval> LiveRecognizer::take_final() {
  // A final silence at the end may still grow: it is held back until something follows it or the
  // audio ends, so that a pause reaches the caller as one silence, not one per piece of audio.
  const bool hold_last = !finished_ && !final_.empty() && final_.back().label.empty();
  std::vector<LabeledInterval> taken(final_.begin(), final_.end() - (hold_last ? 1 : 0));
  final_.erase(final_.begin(), final_.end() - (hold_last ? 1 : 0));
  if (!taken.empty()) taken_us_ = taken.back().end_us;
  return taken;
}

std::vector<LabeledInterval> LiveRecognizer::guess() const {
  std::vector<LabeledInterval> guess = final_;
  guess.insert(guess.end(), guess_.begin(), guess_.end());
  return guess;
}

std::vector<std::string> LiveRecognizer::take_notes() {
  std::vector<std::string> taken;
  taken.swap(notes_);
  return taken;
}

}  // namespace lipsync::speech
