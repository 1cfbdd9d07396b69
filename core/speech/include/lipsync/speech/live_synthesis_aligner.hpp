// Live audio in any espeak-ng language with a transcript: the offline warp against espeak-ng's
// rendering (dtw_aligner.hpp), done in windows as the audio arrives.
//
// The transcript is spoken by espeak-ng a few sentences at a time, each when the speech comes
// within 30 s of it (words that come later are queued after it; words of a sentence whose end has
// not come wait for it while the rendering reaches 0.3 s past the newest audio, so that words that
// come one at a time are not spoken as one-word sentences; and when a part of a sentence had to be
// spoken before its end came, the words that continue it are spoken together with its rest that
// the speech has not reached, the rendering cut before that rest: up to 40 words are spoken again),
// and its MFCC frames are the rows of the
// warp; the recording's frames are its columns. The window runs from the anchor, the end of the last final phone (in
// the recording) and the start of the next phone (in the rendering), to the newest audio heard. After each piece the
// warp is searched from the anchor with an open end: the path must end at the newest column, at whichever row gives the
// lowest mean distance, so the rendering need not be heard to its end. The rendering's boundaries up to that row are
// carried across it with the offline rules (carried_boundary_rules.hpp: stops from their closures, sounds after a pause
// from the recording's speech, /m/ from its murmur, voiced /b/ from its closure) and the closure refiner moves the lip
// phones to the recording's energy steps. Phones that end `commit_us` or more before the newest
// audio become final, and the anchor moves to the last of them; the rest are the guess.
//
// Speakers pause where espeak-ng does not. The offline aligner puts such pauses into the rendering
// and warps again; here the recording's runs of pause-level frames (35 dB under the loudest heard)
// longer than `pause_cut_us` are cut out of the window before the warp (the first 40 ms of each
// and the 60 ms before the speech that follows are kept: a stop's closure), and come back as
// silence in the phones. A pause that lasts becomes final silence as it goes, so the window (and
// the audio kept) stays as long as the commit delay, however long the stream and its pauses.
//
// The recording's features are normalised by the stream so far (its loudest band and its means,
// drawn toward the rendering's means over the first second), not by the window alone.
//
// Words with times (a TTS's word marks, add_timed_words) place the speech after each pause, as the
// English recogniser places an utterance: once the speech comes out of a pause longer than
// `pause_cut_us` (the stream's first pause aside), the audio after it is warped from the first
// timed word that starts after the pause's middle (from the rendering's pause before that word,
// where espeak-ng makes one; espeak-ng's word events give each word's first phone), the audio
// before it as before, and the pause is silence. So a stretch the warp got wrong (speech the words
// do not describe, noise) does not drag the rest of the stream. Without times nothing of this
// happens.
//
// Audio before any word, or after the transcript's last, shows as silence (there is no phone loop
// in other languages) and a note says so. Not thread-safe: one stream, one aligner.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/dtw_aligner.hpp"
#include "lipsync/speech/live_phone_source.hpp"

namespace lipsync::speech {

struct LiveSynthesisOptions {
  /// Words spoken in the audio ("" when every word comes later, add_words).
  std::string transcript;
  /// The voice that speaks the transcript: its language is the recording's.
  SynthesisOptions synthesis;
  /// Rate of the samples pushed (8000 to 48000); they are resampled to 16 kHz.
  int sample_rate_hz = 16000;
  /// Phones ending this long before the newest audio are final, µs.
  std::int64_t commit_us = 400'000;
  /// Pause-level runs of the recording longer than this are cut from the warp and become silence, µs.
  std::int64_t pause_cut_us = 150'000;
  /// What matching one frame to many costs in the warp (as offline).
  StretchCost stretch;
  /// Move the lip phones' boundaries to the energy steps of the recording.
  bool refine_closures = true;
  ClosureRefinerOptions refiner = dtw_refiner_options();
};

class LiveSynthesisAligner final : public LivePhoneSource {
 public:
  /// Speaks the transcript (when not empty). Throws InputError naming `source`: an unknown voice, a
  /// transcript espeak-ng cannot speak, a sample rate outside 8000-48000.
  LiveSynthesisAligner(const LiveSynthesisOptions& options, std::string source);
  ~LiveSynthesisAligner() override;

  void add_words(std::string_view text) override;
  /// Adds the words as add_words does; their times (µs from the stream's first sample, in order)
  /// place the speech after each pause (above). Throws InputError naming the word (its number in
  /// the whole transcript): one without letters or digits, one that starts before the timed word
  /// before it (or before 0). Nothing is added when one is refused.
  void add_timed_words(std::span<const TimedWord> words) override;
  std::size_t words_ahead() const override;

  void push(std::span<const std::int16_t> samples) override;
  void finish() override;

  std::vector<LabeledInterval> take_final() override;
  std::vector<LabeledInterval> guess() const override;
  std::int64_t heard_us() const override { return heard_us_; }
  std::vector<std::string> take_notes() override;

  /// How far the final phones reach, µs.
  std::int64_t final_us() const { return final_us_; }
  /// The rendering's phones (every word spoken so far by espeak-ng), pauses included.
  std::size_t rendering_phones() const { return phones_base_ + phones_.size(); }
  /// The rendering's frames held (those more than a minute behind the anchor are dropped), and all
  /// it has had.
  std::size_t rendering_frames_held() const { return rows_.size(); }
  std::size_t rendering_frames() const { return rows_base_ + rows_.size(); }
  /// Times the unheard rest of an open sentence was spoken again with the words that continue it.
  std::size_t respoken() const { return respoken_; }

 private:
  struct Window;
  /// Where a pause splits the window: window frames [silence_from, speech_from) are silence, and
  /// the speech from speech_from on is warped from rendering phone `phone`.
  struct Split {
    std::size_t silence_from = 0;
    std::size_t speech_from = 0;
    std::size_t phone = 0;
  };
  struct TimedStart {
    std::size_t word = 0;  // its number in the stream's words, from 0
    std::int64_t start_us = 0;
  };
  struct PendingWords {
    std::string text;
    std::string what;  // for errors: "the transcript (words 1-14)", "words 15-20"
    std::size_t count = 0;
    std::size_t first_word = 0;  // 1-based
    bool ends_sentence = false;  // its last word ends with . ! or ?
  };
  void queue_words(std::string_view text, const std::string& what);
  void speak_words_due(bool ended = false);
  /// Speaks `words` after the rendering, with the unheard rest of the open sentence before them.
  void speak(PendingWords words);
  /// Drops the rendering from spoken word `word`, whose first phone is `phone`, on.
  void cut_rendering_at(std::size_t word, std::size_t phone);
  void append_rendering(std::string_view text, std::string_view what);
  void measure_new_frames();
  void update(bool ended);
  /// Window frames [from, to) of the recording with their long pauses cut.
  Window cut_window(std::size_t from, std::size_t to, double quiet_below_db) const;
  /// The phones heard in `window`, warped against the rendering from phone `first_phone` on: on the
  /// stream's clock, tiling [start_us, end_us), the window's cuts silent. Empty when the window is
  /// too short to warp or the rendering has no rows left there.
  std::vector<LabeledInterval> hear(const Window& window, std::size_t first_phone, std::int64_t start_us,
                                    std::int64_t end_us);
  /// With timed words: whether the window holds a pause that the speech has come out of and that
  /// the times place (see the top of this file); the first such is `split`.
  bool find_split(std::size_t frames, double quiet_below_db, Split& split);
  /// The first rendering phone of the first timed word starting at or after `from_us` whose phones are
  /// held (its words are spoken first if they are still queued).
  std::optional<std::size_t> timed_phone_after(std::int64_t from_us);
  /// The stream's time of window frame `frame` (frames from the anchor's frame), µs.
  std::int64_t frame_us(std::size_t frame) const;
  void finalise_silence_until(std::int64_t end_us);
  void move_anchor_to(std::int64_t end_us, std::size_t next_phone);
  void drop_behind_anchor();
  void cover_heard_with_guess();
  /// The rendering's row where the next phone (the first not final) starts; its end without one.
  std::size_t next_phone_row() const;
  /// The rendering's row where phone `phone` starts; its end for a phone past the last.
  std::size_t phone_row(std::size_t phone) const;

  LiveSynthesisOptions options_;
  std::string source_;
  StreamingResampler resampler_;
  std::vector<std::int16_t> resampled_;  // scratch

  // The rendering: its frames (rows), their pause flags, its phones (stops from their closures,
  // times on the rendering's clock) and their bursts, from rows_base_ and phones_base_ on.
  FeatureFrames rows_;
  std::vector<bool> rows_quiet_;
  std::size_t rows_base_ = 0;
  std::vector<LabeledInterval> phones_;  // line: the word count before the phone's chunk
  std::vector<std::int64_t> bursts_us_;
  std::size_t phones_base_ = 0;
  std::vector<double> rendering_means_;
  std::size_t words_ = 0;             // words spoken by espeak-ng so far
  std::deque<PendingWords> pending_;  // words not spoken yet, in chunks of sentences
  std::size_t queued_words_ = 0;      // words given so far
  // The sentence spoken last while its end has not come yet: its words (as given) from stream word
  // open_sentence_first_ on, up to words_; empty when the last words spoken ended a sentence.
  std::vector<std::string> open_sentence_;
  std::size_t open_sentence_first_ = 0;
  std::size_t respoken_ = 0;
  // Each spoken word's first rendering phone (-1: espeak-ng spoke none), from word word_phones_base_
  // on; the words that came with times, in order, and the last one's time.
  std::vector<std::int64_t> word_phones_;
  std::size_t word_phones_base_ = 0;
  std::vector<TimedStart> timed_words_;
  std::int64_t last_timed_us_ = 0;
  // The starts of the recording's pauses seen beginning (stream µs), from that of the pause the
  // anchor may be in on: where a pause that the anchor has moved into began.
  std::vector<std::int64_t> pause_starts_us_;

  // The recording from the anchor's frame on (16 kHz), each 10 ms frame's level, the loudest.
  std::vector<std::int16_t> audio_;
  std::int64_t audio_base_sample_ = 0;  // a multiple of the 10 ms hop
  std::vector<double> levels_db_;       // frames from audio_base_sample_ / hop on
  double loudest_level_db_ = -200.0;
  FeatureNormalisation normalisation_;
  std::vector<double> mean_sums_;
  std::size_t counted_frames_ = 0;  // frames of the stream up to the last whose features are in mean_sums_
  std::size_t mean_count_ = 0;      // frames in mean_sums_ (the speech's: pause-level frames are left out)

  // The anchor: the first rendering phone not final yet.
  std::size_t next_phone_ = 0;
  std::vector<LabeledInterval> final_;  // final, not yet taken
  std::vector<LabeledInterval> guess_;
  std::int64_t final_us_ = 0;
  std::int64_t heard_us_ = 0;
  std::int64_t samples_in_ = 0;  // at the rate pushed: heard_us_ is theirs
  bool finished_ = false;
  bool said_silence_ = false;
  std::vector<std::string> notes_;
};

}  // namespace lipsync::speech
