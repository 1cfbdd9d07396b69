// The Festival recordings in other languages of tests/data/recorded_languages (made by
// tools/speech/measure_language_alignment.py --corpus): each NAME.wav with its voice and transcript
// (NAME.txt: the espeak-ng voice on the first line, the words on the second) and, from
// NAME.truth.tsv (Festival's own segment times matched to espeak-ng's phonemes), the middle of each
// bilabial closure Festival spoke: halfway to the start of the phone after it where the truth has
// that phone, else 25 ms into the closure.
#pragma once

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "lipsync/speech/audio.hpp"

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

}  // namespace lipsync::testing
