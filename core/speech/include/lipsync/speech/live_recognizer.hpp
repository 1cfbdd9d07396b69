// Live audio in: timed phonemes from speech as it arrives, for a face that moves while the
// speaker is still speaking.
//
// The offline aligner (aligner.hpp) hears a whole recording before it says anything. Here the
// audio comes in pieces and PocketSphinx decodes each piece as it comes (ps_process_raw on an
// open utterance): its partial hypothesis is the best path through everything heard so far. Its
// last phones still change as more audio comes, its earlier ones settle. So the recogniser keeps
// two kinds of phones on one timeline that starts at the first sample:
//   - final phones, which never change again: those ending at least `commit_us` before the newest
//     audio decoded, and all of an utterance once it has ended;
//   - the guess: the partial hypothesis after the final phones, up to the newest audio decoded,
//     which the caller may show (the live renderer does, up to a settling margin) but which may
//     change with the next piece.
// Both are ARPAbet, "" is silence, and the lip phones' boundaries are moved to the energy steps
// of the signal as the offline path moves them (closure_refiner.hpp), over the audio heard so far.
//
// Utterances are cut at pauses, so that the decoder's state does not grow with the stream: a
// 10 ms frame is voiced when its level is 15 dB over the noise floor (the quietest frame of the
// last 1.5 s, so that a steady noise is the floor within 1.5 s of its start) and above -55 dBFS; an utterance opens at
// the first voiced frame, with `pre_roll_us` of the audio before it, and ends after `end_pause_us` without a voiced
// frame, or at `max_utterance_us`. Audio outside utterances is never decoded (silence costs almost nothing) and becomes
// final silence at once.
//
// With a transcript the utterance is force-aligned to it as it is heard: a JSGF grammar of the
// next `transcript_window_words` words, each a prefix of the rest (an utterance may stop after
// any word), whose one-phone words carry their word's place in the window; the next utterance
// starts after the last word the previous one held. Without one the phones are recognised with
// the phonetic language model (PocketSphinx's allphone search).
//
// The transcript may grow while the audio comes (a TTS that speaks an LLM's reply sentence by
// sentence): add_words() appends words. A grammar is fixed once its utterance opens, so when the
// hypothesis nears the last words of its grammar and more words have come since (or the
// utterance opened before any word had come and runs on the phone loop), the utterance so far is
// decoded again with a grammar of the words known now; phones already final stay as they are.
// That costs the utterance's audio again (a few ms per second of it): send the words ahead of
// their audio and it never happens. Words may carry times (add_timed_words: from a TTS's word
// marks): then an utterance starts its grammar at the first timed word that starts after the
// middle of the pause before it, so a stream finds its place in the transcript again after a
// stretch the recogniser got wrong. The times say where
// the words are, the audio where the phones are.
//
// A grammar utterance with `mismatch_voiced_us` of voice in which not one word was heard is
// reported in the notes: the speech does not follow the transcript there.
//
// Not thread-safe: one stream, one recogniser, one thread at a time. Loading the model takes
// about half a second; decoding costs about 0.1-0.3 of the audio's real time on one core. That
// half second can be spent ahead: prepare_live_decoder() loads a decoder (on any thread), and a
// recogniser made with it starts at once and decodes exactly as one that loaded its own.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/speech/closure_refiner.hpp"
#include "lipsync/speech/live_phone_source.hpp"
#include "lipsync/utterance.hpp"
#include "lipsync/word_marks.hpp"

namespace lipsync::speech {

struct LiveRecognitionOptions {
  /// Words spoken in the audio (punctuation and case ignored); none: recognise phones. Set to ""
  /// when the words come later (add_words, add_timed_words).
  std::optional<std::string> transcript;
  /// The acoustic model directory's parent, holding en-us/, cmudict-en-us.dict, en-us-phone.lm.bin.
  std::string model_dir = "/usr/share/pocketsphinx/model/en-us";
  /// Rate of the samples pushed (8000 to 48000); they are resampled to the model's 16 kHz.
  int sample_rate_hz = 16000;
  /// Phones ending this long before the newest audio decoded are final, µs.
  std::int64_t commit_us = 400'000;
  /// Silence that ends an utterance, µs.
  std::int64_t end_pause_us = 350'000;
  /// The longest utterance: one that reaches it is ended there, µs.
  std::int64_t max_utterance_us = 20'000'000;
  /// Audio before an utterance's first voiced frame that is decoded with it (a stop's silent
  /// closure, the decoder's sense of silence), µs.
  std::int64_t pre_roll_us = 200'000;
  /// Transcript words one utterance's grammar holds at most.
  std::size_t transcript_window_words = 40;
  /// Voice in a grammar utterance without a word heard that is reported as a mismatch, µs.
  std::int64_t mismatch_voiced_us = 1'000'000;
  /// Move the lip phones' boundaries to the signal's energy steps (closure_refiner.hpp).
  bool refine_closures = true;
  ClosureRefinerOptions refiner;
  /// PocketSphinx's beams without a transcript (-beam, -pbeam, -wbeam): narrower is cheaper;
  /// 1e-6 already loses the path on synthetic speech.
  double phone_beam = 1e-8;
  /// Without a transcript, the Gaussians PocketSphinx scores per senone (-topn; 4 with one too):
  /// 2 halves the phone loop's cost and loses closures on recorded people's speech.
  int phone_top_gaussians = 4;
};

/// A PocketSphinx decoder loaded for a LiveRecognizer: the acoustic model, the dictionary and,
/// without a transcript, the phone loop. Opaque; made by prepare_live_decoder().
class LiveDecoder;
struct LiveDecoderDeleter {
  void operator()(LiveDecoder* decoder) const;
};
using PreparedLiveDecoder = std::unique_ptr<LiveDecoder, LiveDecoderDeleter>;

/// Loads the decoder a recogniser with `options` needs before its first sample. Of the options
/// only these matter (same_live_decoder): whether a transcript is set, model_dir, phone_beam and
/// phone_top_gaussians. Throws InputError naming `source`: a missing or unreadable model.
PreparedLiveDecoder prepare_live_decoder(const LiveRecognitionOptions& options, const std::string& source);
/// Whether a decoder prepared for `prepared_for` serves a recogniser made with `options`.
bool same_live_decoder(const LiveRecognitionOptions& prepared_for, const LiveRecognitionOptions& options);

class LiveRecognizer final : public LivePhoneSource {
 public:
  /// Loads the model, or takes `prepared` when it was prepared for such options (else it is
  /// dropped and the model loaded). `source` names the stream in errors. Throws InputError: a
  /// missing model, a sample rate outside 8000-48000, a word the dictionary lacks.
  LiveRecognizer(const LiveRecognitionOptions& options, std::string source, PreparedLiveDecoder prepared = {});
  ~LiveRecognizer() override;

  /// More words of the transcript, after those given so far. Throws InputError naming the word
  /// (its number in the whole transcript) when the dictionary lacks it, or when the recogniser was
  /// made without a transcript; the words before it are added.
  void add_words(std::string_view text) override;
  /// The same for words with times; a word's start_us must not be before the previous timed word's.
  void add_timed_words(std::span<const TimedWord> words) override;
  /// Words added and not yet reached by an utterance (the transcript ahead of the speech).
  std::size_t words_ahead() const override { return words_base_ + words_.size() - std::min(next_word_, words_end()); }

  /// Decodes the next samples (at options.sample_rate_hz).
  void push(std::span<const std::int16_t> samples) override;
  /// The audio has ended: the open utterance is decoded to its end and every phone is final.
  void finish() override;

  /// Phones that became final since the last call, in order, contiguous with the ones taken before:
  /// together they tile [0, taken_us()). A final silence at the end is held back until something
  /// follows it or the audio ends (a pause arrives as one silence, not one per piece of audio).
  std::vector<LabeledInterval> take_final() override;
  /// Everything after the phones taken, up to the newest audio decoded: the final silence held
  /// back, then the guess; tiles [taken_us(), heard_us()) (empty when they meet).
  std::vector<LabeledInterval> guess() const override;
  /// How far the phones taken so far reach, µs.
  std::int64_t taken_us() const { return taken_us_; }
  /// How far the final phones reach, µs.
  std::int64_t final_us() const { return final_us_; }
  /// How far the audio has been decoded (or, outside utterances, classified), µs.
  std::int64_t heard_us() const override { return heard_us_; }
  /// Utterances ended so far.
  std::size_t utterances() const { return utterances_; }
  /// Times an open utterance was decoded again because its grammar's words ran out.
  std::size_t redecodes() const { return redecodes_; }
  /// Things the user should know about the stream ("a word not heard", ...), since the last call.
  std::vector<std::string> take_notes() override;

 private:
  struct Word {
    std::string text;
    std::int64_t start_us = -1;  // -1: untimed
  };

  void add_word(std::string text, std::int64_t start_us);
  std::size_t words_end() const { return words_base_ + words_.size(); }
  const Word& word(std::size_t w) const { return words_[w - words_base_]; }
  void use_phone_loop();
  void process_frame(std::span<const std::int16_t> frame);
  void open_utterance();
  std::size_t first_word_of_utterance() const;
  void start_search();
  void decode_queued();
  void redecode_if_words_ran_out();
  void note_how_the_transcript_went();
  void close_utterance();
  void update_phones(bool ended);
  std::int64_t sample_us(std::int64_t sample) const;

  LiveRecognitionOptions options_;
  std::string source_;
  PreparedLiveDecoder decoder_;
  bool has_transcript_ = false;
  // The transcript's words from words_base_ on (those far behind the speech are dropped, so that a
  // transcript growing for hours keeps a flat memory), numbered from the stream's first word.
  std::deque<Word> words_;
  std::size_t words_base_ = 0;
  std::size_t next_word_ = 0;  // the first word the next utterance may hold
  bool said_words_ran_out_ = false;

  std::vector<std::int16_t> resampled_;                       // scratch: this push's audio at 16 kHz
  std::vector<std::int16_t> frame_;                           // the 10 ms frame being filled
  std::vector<std::int16_t> pre_roll_;                        // the last pre_roll_us of audio outside utterances
  std::int64_t samples_seen_ = 0;                             // 16 kHz samples classified so far
  std::deque<std::pair<std::int64_t, double>> floor_window_;  // (frame, level dBFS): the floor's candidates
  std::int64_t frames_classified_ = 0;

  bool open_ = false;
  std::int64_t utterance_first_sample_ = 0;    // where the open utterance's audio starts
  std::int64_t utterance_voice_us_ = 0;        // where its first voiced frame starts
  std::int64_t last_voice_end_us_ = 0;         // where the last utterance's last voiced frame ended
  std::vector<std::int16_t> utterance_audio_;  // all of it, for the closure refiner
  std::int64_t silent_samples_ = 0;            // since its last voiced frame
  std::vector<std::int16_t> decode_queue_;     // its audio not yet handed to the decoder
  std::size_t grammar_first_ = 0;              // its grammar's words: [grammar_first_, grammar_end_);
  std::size_t grammar_end_ = 0;                //   empty: the phone loop
  std::int64_t max_word_heard_ = -1;           // the last transcript word its hypothesis holds
  std::int64_t voiced_samples_ = 0;            // its voiced frames' samples

  std::vector<LabeledInterval> final_;  // final, not yet taken
  std::vector<LabeledInterval> guess_;
  std::int64_t final_us_ = 0;
  std::int64_t taken_us_ = 0;
  std::int64_t heard_us_ = 0;
  bool finished_ = false;
  std::size_t utterances_ = 0;
  std::size_t redecodes_ = 0;
  std::vector<std::string> notes_;
};

}  // namespace lipsync::speech
