// The Festival recordings in other languages of tests/data/recorded_languages (made by
// tools/speech/measure_language_alignment.py --corpus): each NAME.wav with its voice and transcript
// (NAME.txt: the espeak-ng voice on the first line, the words on the second) and, from
// NAME.truth.tsv (Festival's own segment times matched to espeak-ng's phonemes), the middle of each
// bilabial closure Festival spoke: halfway to the start of the phone after it where the truth has
// that phone, else 25 ms into the closure.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "lipsync/speech/audio.hpp"
#include "lipsync/word_marks.hpp"

namespace lipsync::testing {

struct RecordedLanguage {
  std::string voice, transcript;
  speech::PcmAudio audio;
  std::vector<std::int64_t> bilabial_middles_us;
};

inline RecordedLanguage recorded_language(const std::string& name) {
  const auto corpus = std::filesystem::path(LIPSYNC_TEST_DATA_DIR) / "recorded_languages";
  const auto read = [&](const std::string& file) {
    std::ifstream in(corpus / file, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  RecordedLanguage item;
  std::istringstream text(read(name + ".txt"));
  std::getline(text, item.voice);
  std::getline(text, item.transcript);
  item.audio = speech::decode_wav(read(name + ".wav"), name + ".wav").audio;
  struct Row {
    double start_s = 0;
    std::size_t index = 0;
    int kind = 0;  // bit 1: a scored boundary; bit 2: a bilabial closure
  };
  std::vector<Row> rows;
  std::istringstream truth(read(name + ".truth.tsv"));
  for (std::string line; std::getline(truth, line);) {
    if (line.empty() || line.front() == '#') continue;
    std::istringstream fields(line);
    std::string festival_label, aligned_label;
    Row row;
    fields >> festival_label >> row.start_s >> row.index >> aligned_label >> row.kind;
    rows.push_back(row);
  }
  for (std::size_t r = 0; r < rows.size(); ++r) {
    if ((rows[r].kind & 2) == 0) continue;
    const bool next_known = r + 1 < rows.size() && rows[r + 1].index == rows[r].index + 1;
    const double end_s = next_known ? rows[r + 1].start_s : rows[r].start_s + 0.05;
    item.bilabial_middles_us.push_back(std::llround((rows[r].start_s + end_s) / 2 * 1e6));
  }
  return item;
}

/// The stretch of `audio` that is speech, µs: from the first to the last 10 ms within 35 dB of the
/// loudest.
inline std::pair<std::int64_t, std::int64_t> speech_span_us(const speech::PcmAudio& audio) {
  const std::size_t hop = static_cast<std::size_t>(audio.sample_rate_hz / 100);
  std::vector<double> levels_db;
  for (std::size_t at = 0; at + hop <= audio.samples.size(); at += hop) {
    double energy = 1e-12;
    for (std::size_t i = at; i < at + hop; ++i) energy += std::pow(audio.samples[i] / 32768.0, 2) / double(hop);
    levels_db.push_back(10 * std::log10(energy));
  }
  const double loud_db = *std::max_element(levels_db.begin(), levels_db.end()) - 35;
  const auto first = std::find_if(levels_db.begin(), levels_db.end(), [&](double db) { return db > loud_db; });
  const auto last = std::find_if(levels_db.rbegin(), levels_db.rend(), [&](double db) { return db > loud_db; });
  return {(first - levels_db.begin()) * 10'000, (levels_db.rend() - last) * 10'000};
}

/// `item`'s words with times as a TTS gives them, on a stream where its audio starts at `offset_us`:
/// the first at the start of its speech, the others spread over the speech by their letters (marks
/// a little off, as a TTS's are).
inline std::vector<TimedWord> timed_words_of(const RecordedLanguage& item, std::int64_t offset_us) {
  const auto [from_us, to_us] = speech_span_us(item.audio);
  std::vector<std::string> words;
  std::istringstream text(item.transcript);
  std::size_t letters = 0;
  for (std::string word; text >> word; letters += word.size()) words.push_back(word);
  std::vector<TimedWord> timed;
  std::size_t before = 0;
  for (const std::string& word : words) {
    timed.push_back(
        {word, offset_us + from_us +
                   (to_us - from_us) * static_cast<std::int64_t>(before) / static_cast<std::int64_t>(letters)});
    before += word.size();
  }
  return timed;
}

}  // namespace lipsync::testing
