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

std::string beam_text(double beam) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", beam);
  return text;
}

}  // namespace

struct LiveRecognizer::Decoder {
  ps_decoder_t* ps = nullptr;
  StreamingResampler resampler;
  // The cepstral means the model starts with. PocketSphinx carries its running means from one
  // utterance to the next, and the digital silence a synthesiser leaves at an utterance's end drags
  // them far from speech: the next utterance then decodes to silence. Each utterance starts from
  // these, as the first does, so that each is decoded as if it were the stream's first.
  std::vector<mfcc_t> initial_means;

  void remember_means() {
    feat_t* feat = ps_get_feat(ps);
    initial_means.assign(static_cast<std::size_t>(feat_cepsize(feat)), 0);
    cmn_live_get(feat->cmn_struct, initial_means.data());
  }
  void restore_means() { cmn_live_set(ps_get_feat(ps)->cmn_struct, initial_means.data()); }
  // Two grammar names, used in turn: replacing the search in use would free it under the decoder.
  int grammar_turn = 0;
  bool phone_loop_built = false;

  Decoder(int rate_hz) : resampler(rate_hz, kModelRateHz) {}
  ~Decoder() {
    if (ps != nullptr) ps_free(ps);
  }
};

LiveRecognizer::LiveRecognizer(const LiveRecognitionOptions& options, std::string source)
    : options_(options), source_(std::move(source)) {
  if (options_.sample_rate_hz < 8000 || options_.sample_rate_hz > 48000) {
    throw InputError(
        source_, 0,
        "sample rate " + std::to_string(options_.sample_rate_hz) + " Hz: live audio takes 8000 to 48000 Hz");
  }
  const std::string hmm = options_.model_dir + "/en-us";
  const std::string dict = options_.model_dir + "/cmudict-en-us.dict";
  const std::string phone_lm = options_.model_dir + "/en-us-phone.lm.bin";
  for (const std::string& path : {hmm + "/mdef", dict, phone_lm}) {
    if (!is_file(path)) {
      throw InputError(
          source_, 0,
          "the PocketSphinx model is missing (" + path + "; install it with 'apt-get install pocketsphinx-en-us')");
    }
  }
  if (options_.transcript) {
    words_ = transcript_words(*options_.transcript);
    if (words_.empty()) throw InputError(source_, 0, "the transcript has no words");
  }
  err_set_logfp(nullptr);  // PocketSphinx logs to stderr by default
  // The phone loop as the offline aligner runs it (the phonetic LM at weight 2) with narrower beams;
  // the transcript's grammar as the offline forced alignment runs it (beams all but open, weight 6.5).
  const bool forced = !words_.empty();
  const std::string beam = forced ? "1e-200" : beam_text(options_.phone_beam);
  cmd_ln_t* config =
      cmd_ln_init(nullptr, ps_args(), TRUE, "-hmm", hmm.c_str(), "-dict", dict.c_str(), "-samprate", "16000",
                  "-remove_silence", "no", "-beam", beam.c_str(), "-pbeam", beam.c_str(), "-wbeam", beam.c_str(),
                  "-bestpath", "no", "-fsgusefiller", "no", "-lw", forced ? "6.5" : "2.0", nullptr);
  if (config == nullptr) throw InputError(source_, 0, "cannot configure PocketSphinx");
  decoder_ = std::make_unique<Decoder>(options_.sample_rate_hz);
  decoder_->ps = ps_init(config);
  cmd_ln_free_r(config);
  if (decoder_->ps == nullptr)
    throw InputError(source_, 0, "cannot load the PocketSphinx model from " + options_.model_dir);
  // The phone loop costs about a quarter of a second to build: with a transcript it is built only
  // if the speech outlasts the transcript's words.
  if (!forced) use_phone_loop();
  if (forced) {
    detail::add_word(decoder_->ps, detail::kPauseWord, "SIL");
    for (std::size_t w = 0; w < words_.size(); ++w) {
      if (detail::pronunciations(decoder_->ps, words_[w]).empty()) {
        throw InputError(source_, 0,
                         "transcript word " + std::to_string(w + 1) + " '" + words_[w] +
                             "' is not in the pronouncing dictionary (write numbers and abbreviations out as words)");
      }
    }
  }
  decoder_->remember_means();
  frame_.reserve(kFrameSamples);
}

LiveRecognizer::~LiveRecognizer() = default;

void LiveRecognizer::use_phone_loop() {
  if (!decoder_->phone_loop_built) {
    const std::string phone_lm = options_.model_dir + "/en-us-phone.lm.bin";
    if (ps_set_allphone_file(decoder_->ps, "phones", phone_lm.c_str()) != 0) {
      throw InputError(source_, 0, "cannot load the phonetic language model " + phone_lm);
    }
    decoder_->phone_loop_built = true;
  }
  ps_set_search(decoder_->ps, "phones");
}

std::int64_t LiveRecognizer::sample_us(std::int64_t sample) const { return sample * 1'000'000 / kModelRateHz; }

void LiveRecognizer::push(std::span<const std::int16_t> samples) {
  resampled_.clear();
  decoder_->resampler.push(samples, resampled_);
  for (const std::int16_t sample : resampled_) {
    frame_.push_back(sample);
    if (frame_.size() == static_cast<std::size_t>(kFrameSamples)) {
      process_frame(frame_);
      frame_.clear();
    }
  }
  if (open_ && !decode_queue_.empty()) {
    ps_process_raw(decoder_->ps, decode_queue_.data(), decode_queue_.size(), FALSE, FALSE);
    decode_queue_.clear();
    update_phones(false);
  }
}

void LiveRecognizer::finish() {
  resampled_.clear();
  decoder_->resampler.finish(resampled_);
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
  const std::int64_t length_us = sample_us(static_cast<std::int64_t>(utterance_audio_.size()));
  if (sample_us(silent_samples_) >= options_.end_pause_us || length_us >= options_.max_utterance_us) {
    close_utterance();
  }
}

void LiveRecognizer::open_utterance() {
  ps_decoder_t* ps = decoder_->ps;
  if (!words_.empty() && next_word_ < words_.size()) {
    // The next words, each a prefix of the rest: "[pause] [ (w1 [ (w2 [ ... [pause] ]) ]) ]". No pause
    // between two words: the partial hypothesis is the best path ending at the newest frame that
    // has a word exit, and a pause, which may exit at every frame, would win it over the words
    // whenever the voice is far from the model's (espeak-ng's); a pause long enough to matter ends
    // the utterance instead, and a shorter silence after the last voiced frame is cut off the
    // phones (update_phones).
    const std::size_t last = std::min(words_.size(), next_word_ + options_.transcript_window_words);
    const std::string pause = std::string(detail::kPauseWord);
    std::string tail;
    for (std::size_t w = last; w-- > next_word_;) {
      std::string alternatives;
      for (const std::string& pronunciation : detail::pronunciations(ps, words_[w])) {
        if (!alternatives.empty()) alternatives += " |";
        std::istringstream phones(pronunciation);
        for (std::string phone; phones >> phone;) {
          const std::string word = detail::phone_word(phone, w);
          detail::add_word(ps, word, phone);
          alternatives += " " + word;
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
    if (!words_.empty() && next_word_ >= words_.size() && utterances_ > 0) {
      notes_.push_back("speech after the transcript's last word: its phones are recognised without it");
      next_word_ = words_.size() + 1;  // say it once
    }
    use_phone_loop();
  }
  open_ = true;
  utterance_first_sample_ = samples_seen_ - static_cast<std::int64_t>(pre_roll_.size());
  utterance_audio_ = pre_roll_;
  decode_queue_ = pre_roll_;
  pre_roll_.clear();
  silent_samples_ = 0;
  max_word_heard_ = -1;
  decoder_->restore_means();
  // A stream of its own per utterance: PocketSphinx numbers an utterance's frames from the start of
  // its stream, and the segments' frames are read as counted from the utterance's first sample.
  ps_start_stream(ps);
  ps_start_utt(ps);
}

void LiveRecognizer::close_utterance() {
  if (!decode_queue_.empty()) {
    ps_process_raw(decoder_->ps, decode_queue_.data(), decode_queue_.size(), FALSE, FALSE);
    decode_queue_.clear();
  }
  ps_end_utt(decoder_->ps);
  update_phones(true);
  if (!words_.empty() && max_word_heard_ >= 0) {
    next_word_ = std::max(next_word_, static_cast<std::size_t>(max_word_heard_) + 1);
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
    max_word_heard_ = std::max(max_word_heard_, index);
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
