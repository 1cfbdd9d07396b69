// What the live path (the Listen call, docs/streaming.md "Live audio") asks of whatever hears a
// voice as it arrives: audio in, phones out in two kinds. Final phones never change again; the guess
// covers the rest of the audio heard and may change with the next piece. Two hear this way:
// LiveRecognizer (English: PocketSphinx, with or without a transcript) and LiveSynthesisAligner (any
// espeak-ng voice with a transcript: a warp against espeak-ng's rendering of it).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lipsync/utterance.hpp"
#include "lipsync/word_marks.hpp"

namespace lipsync::speech {

class LivePhoneSource {
 public:
  virtual ~LivePhoneSource() = default;
  LivePhoneSource() = default;
  LivePhoneSource(const LivePhoneSource&) = delete;
  LivePhoneSource& operator=(const LivePhoneSource&) = delete;
  LivePhoneSource(LivePhoneSource&&) = delete;
  LivePhoneSource& operator=(LivePhoneSource&&) = delete;

  /// More words of the transcript, after those given so far. Throws InputError naming the word
  /// when it cannot be heard (or when there is no transcript); the words before it are added.
  virtual void add_words(std::string_view text) = 0;
  /// The same for words with times; a word's start_us must not be before the previous timed word's.
  virtual void add_timed_words(std::span<const TimedWord> words) = 0;
  /// Words added and not yet reached by the speech (the transcript ahead of it).
  virtual std::size_t words_ahead() const = 0;

  /// Hears the next samples (at the rate the source was made for).
  virtual void push(std::span<const std::int16_t> samples) = 0;
  /// The audio has ended: every phone is final.
  virtual void finish() = 0;

  /// Phones that became final since the last call, in order, contiguous with the ones taken before
  /// (together they tile [0, the end of the last one taken)). A final silence at the end is held back
  /// until something follows it or the audio ends.
  virtual std::vector<LabeledInterval> take_final() = 0;
  /// Everything after the phones taken, up to heard_us(): the final silence held back, then the
  /// guess (empty when they meet).
  virtual std::vector<LabeledInterval> guess() const = 0;
  /// How far the audio has been heard, µs.
  virtual std::int64_t heard_us() const = 0;
  /// Things the user should know about the stream, since the last call.
  virtual std::vector<std::string> take_notes() = 0;
};

}  // namespace lipsync::speech
