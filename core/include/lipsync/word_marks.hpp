// Word marks: the times a text-to-speech service says each word of its audio starts, read from
// the files the services return, for a live stream whose transcript carries word times
// (live_recognizer.hpp, docs/streaming.md "Transcripts that grow, and word times").
//
// Three services' formats are read, told apart by their fields:
//   - Amazon Polly speech marks: JSON lines, one object a mark; the word marks are those with
//     "type": "word", their "time" in integer ms and their text in "value" (sentence, viseme and
//     ssml marks are skipped).
//   - ElevenLabs character alignment: one object with "characters",
//     "character_start_times_seconds" (and "character_end_times_seconds"), at the top or under
//     "alignment" or "normalized_alignment" (as the API returns it); a word is a run of
//     characters without white space and starts when its first character does.
//   - Azure word boundaries: a JSON array or JSON lines of the SDK's WordBoundary events, each
//     with "Text" and "AudioOffset" in ticks of 100 ns, or the service's "audio.metadata"
//     messages ({"Metadata": [{"Type": "WordBoundary", "Data": {"Offset": ticks, "text":
//     {"Text": ...}}}]}); other boundary types (punctuation, sentence) are skipped.
// Times become integer microseconds at once (ms × 1000; seconds rounded to the µs; ticks / 10).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace lipsync {

/// A word and when it starts, µs on the audio's clock (from its first sample).
struct TimedWord {
  std::string text;
  std::int64_t start_us = 0;
};

/// The word marks in `text` (a file's contents), in the order given. `source` names the file in
/// errors. Throws InputError naming the line and field: text that is none of the formats, a mark
/// without its time or text, a time that is negative, beyond 24 h or earlier than the mark before.
std::vector<TimedWord> read_word_marks(std::string_view text, const std::string& source);

}  // namespace lipsync
