// What the offline aligner (aligner.cpp) and the live recogniser (live_recognizer.cpp) both need
// of PocketSphinx, stated once: its frame clock, the phone a recognised "word" stands for, and
// the grammar's one-phone words and pronunciations looked up in the dictionary.
#pragma once

#include <pocketsphinx.h>

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace lipsync::speech::detail {

/// PocketSphinx's frame step (-frate 100).
inline constexpr std::int64_t kFrameUs = 10'000;
/// Frame k analyses the window [k·10 ms, k·10 ms + 25.6 ms] (-wlen 0.025625), centred at
/// k·10 + 12.8 ms. A segment that starts at frame k starts midway between the centres of
/// frames k-1 and k: at k·10 ms + 7.8 ms. (Without this shift the boundaries come out
/// about 9 ms early on synthetic speech with known boundaries, tests/bench/alignment_accuracy.)
inline constexpr std::int64_t kBoundaryOffsetUs = 7'800;
/// The grammar's pause between words (PocketSphinx's silence phone).
inline constexpr const char* kPauseWord = "pause_";

/// Phone label of a recognised "word": "aa_3" → ("AA", 3); a phone from the
/// phonetic LM ("AA") → ("AA", -1); silence and noise fillers → ("", -1).
std::pair<std::string, int> phone_of(std::string_view word);

/// Every pronunciation the dictionary lists for `word` (space-separated phones); none if it is not there.
std::vector<std::string> pronunciations(ps_decoder_t* decoder, const std::string& word);

/// Adds `word` to the decoder's dictionary as `phones` unless it is there already.
void add_word(ps_decoder_t* decoder, const std::string& word, const std::string& phones);

/// The grammar word of `phone` (as the dictionary writes it, "AA") in transcript word `w`: "aa_3".
std::string phone_word(const std::string& phone, std::size_t w);

}  // namespace lipsync::speech::detail
