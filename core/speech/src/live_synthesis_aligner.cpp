// The live warp against espeak-ng's rendering (lipsync/speech/live_synthesis_aligner.hpp). This file
// holds the rendering that grows with the transcript (and where each of its words starts), the
// recording's window and its cut pauses, the split of the window at a pause that timed words
// place, the open-ended warp, and the commit of phones that moves the anchor.
#include "lipsync/speech/live_synthesis_aligner.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <sstream>

#include "carried_boundary_rules.hpp"
#include "lipsync/error.hpp"
#include "rendering_pauses.hpp"

namespace lipsync::speech {
namespace {

constexpr std::int64_t kHopSamples = kFeatureRateHz * kFeatureHopUs / 1'000'000;        // 160
constexpr std::int64_t kWindowSamples = kFeatureRateHz * kFeatureWindowUs / 1'000'000;  // 400
// Silence put before the first words spoken by espeak-ng (which starts speaking at once), so the
// recording's leading pause has pause to match, and after every chunk of words, µs.
constexpr std::int64_t kLeadingPaddingUs = 300'000;
constexpr std::int64_t kTrailingPaddingUs = 100'000;
// A recording frame is at pause level this far under the loudest frame heard, or under kQuietDbfs.
constexpr double kSpeechRangeDb = 35.0;
constexpr double kQuietDbfs = -55.0;
// Of a pause cut from the warp, the frames kept after the speech before it (its decay) and before
// the speech after it (a stop's closure).
constexpr std::size_t kPauseHeadFrames = 4;
constexpr std::size_t kPauseTailFrames = 6;
// Of a pause still going on, the newest audio shown as the warp matched it (the start of the next
// sound, a stop's closure, may be in it); before that it is silence, µs.
constexpr std::int64_t kShownQuietUs = 100'000;
// The rendering's rows a window reaches: this many per recording frame, and this many more (a speaker
// three times as fast as espeak-ng, and a pause of espeak-ng's the speaker leaves out).
constexpr std::size_t kRowsPerColumn = 3;
constexpr std::size_t kExtraRows = 60;
// Frames of the rendering's means that the recording's are drawn toward (a second's worth): until the
// recording has that much speech of its own, its means lean on the rendering's.
constexpr double kPriorFrames = 100.0;
// The transcript is spoken by espeak-ng in chunks of sentences of at least this many words, each
// when the rendering ahead of the anchor is shorter than kRowsSpokenAhead (30 s): a transcript of
// 16 KiB (a quarter of an hour of speech) would take espeak-ng seconds to speak at once.
constexpr std::size_t kChunkWords = 12;
constexpr std::size_t kRowsSpokenAhead = 3000;
// Words of a sentence whose end has not come wait for it while the rendering reaches this many rows
// (0.3 s) past the newest audio's.
constexpr std::size_t kRowsHeldAhead = 30;
// The most words of an open sentence spoken again with the words that continue it: a sentence that
// never ends (a transcript without a full stop) is not spoken again from its start with every word.
constexpr std::size_t kMostWordsSpokenAgain = 40;
// Rendering rows and phones behind the anchor kept before they are dropped (a minute's worth).
constexpr std::size_t kDropRowsAfter = 6000;

std::int64_t sample_us(std::int64_t sample) { return sample * 1'000'000 / kFeatureRateHz; }
std::int64_t us_sample(std::int64_t us) { return us * kFeatureRateHz / 1'000'000; }

/// Whether `word` (or a chunk of words) ends a sentence: its last character is . ! or ?.
bool ends_sentence(std::string_view word) {
  return !word.empty() && (word.back() == '.' || word.back() == '!' || word.back() == '?');
}

std::size_t word_count(std::string_view text) {
  std::istringstream words{std::string(text)};
  std::size_t count = 0;
  for (std::string word; words >> word;) ++count;
  return count;
}

// The cheapest monotone path from (row0, 0) through rows [row0, row0 + row_count) of `rows` and every
// column of `columns`, ending at the last column in whichever row gives the lowest mean distance
// (its cost over rows + columns, as warp() normalises). Steps, costs and stretch charges as warp()'s.
WarpPath open_end_warp(const FeatureFrames& rows, const std::vector<bool>& rows_quiet, std::size_t row0,
                       std::size_t row_count, const FeatureFrames& columns, const std::vector<bool>& columns_quiet,
                       const StretchCost& stretch) {
  enum Step : std::uint8_t { kDiagonal, kDown, kRight };
  const std::size_t column_count = columns.size();
  constexpr double kUnreachable = std::numeric_limits<double>::infinity();
  std::vector<std::uint8_t> steps(row_count * column_count, kDiagonal);
  std::vector<double> previous(column_count, kUnreachable), current(column_count, kUnreachable);
  std::vector<std::int32_t> previous_run(column_count, 0), current_run(column_count, 0);
  std::vector<double> last_column(row_count, kUnreachable);
  const auto free_frames = static_cast<std::int32_t>(stretch.free_frames);
  for (std::size_t i = 0; i < row_count; ++i) {
    for (std::size_t j = 0; j < column_count; ++j) {
      const double distance = frame_distance(rows, row0 + i, columns, j);
      const double run_cost = rows_quiet[row0 + i] || columns_quiet[j] ? 0.0 : stretch.cost;
      double best = kUnreachable;
      if (i == 0 && j == 0) best = distance;
      std::uint8_t step = kDiagonal;
      std::int32_t run = 0;
      if (i > 0 && j > 0 && previous[j - 1] + 2 * distance < best) best = previous[j - 1] + 2 * distance;
      if (i > 0) {
        const std::int32_t down_run = std::max(previous_run[j], 0) + 1;
        const double cost = previous[j] + distance + (down_run > free_frames ? run_cost : 0.0);
        if (cost < best) {
          best = cost;
          step = kDown;
          run = down_run;
        }
      }
      if (j > 0) {
        const std::int32_t right_run = std::max(-current_run[j - 1], 0) + 1;
        const double cost = current[j - 1] + distance + (right_run > free_frames ? run_cost : 0.0);
        if (cost < best) {
          best = cost;
          step = kRight;
          run = -right_run;
        }
      }
      current[j] = best;
      current_run[j] = run;
      steps[i * column_count + j] = step;
    }
    last_column[i] = current[column_count - 1];
    std::swap(previous, current);
    std::swap(previous_run, current_run);
  }
  std::size_t end_row = 0;
  double best_mean = kUnreachable;
  for (std::size_t i = 0; i < row_count; ++i) {
    const double mean = last_column[i] / static_cast<double>(i + 1 + column_count);
    if (mean < best_mean) {
      best_mean = mean;
      end_row = i;
    }
  }
  WarpPath path;
  path.mean_distance = best_mean;
  path.first.assign(end_row + 1, 0);
  path.last.assign(end_row + 1, 0);
  std::size_t i = end_row, j = column_count - 1;
  path.first[i] = j;
  path.last[i] = j;
  while (i > 0 || j > 0) {
    const std::uint8_t step = steps[i * column_count + j];
    if (step == kRight) {
      --j;
    } else {
      if (step == kDiagonal) --j;
      --i;
      path.last[i] = j;
    }
    path.first[i] = j;
  }
  return path;
}

// Appends `interval` to `phones`, one silence for consecutive silences.
void append_merged(std::vector<LabeledInterval>& phones, const LabeledInterval& interval) {
  if (interval.end_us <= interval.start_us) return;
  if (!phones.empty() && phones.back().label.empty() && interval.label.empty()) {
    phones.back().end_us = interval.end_us;
    phones.back().line = std::max(phones.back().line, interval.line);
    return;
  }
  phones.push_back(interval);
}

// `phones` with [from_us, to_us) silent: a phone that spans it keeps its longer side, one that
// reaches into it keeps its part outside, one inside it goes. Each silence carries the index
// (line) of the last rendering phone it finishes, so that a rendering phone the silence took from
// the far side of a pause is heard again after it.
std::vector<LabeledInterval> with_silence(const std::vector<LabeledInterval>& phones, std::int64_t from_us,
                                          std::int64_t to_us) {
  std::vector<LabeledInterval> result;
  for (const LabeledInterval& phone : phones) {
    const bool starts_before = phone.start_us < from_us;
    const bool ends_after = phone.end_us > to_us;
    if (phone.label.empty() || phone.end_us <= from_us || phone.start_us >= to_us) {
      append_merged(result, phone);
    } else if (starts_before && (!ends_after || from_us - phone.start_us >= phone.end_us - to_us)) {
      append_merged(result, {phone.label, phone.start_us, from_us, phone.line});
      append_merged(result, {"", from_us, phone.end_us, phone.line});
    } else if (ends_after) {
      append_merged(result, {"", phone.start_us, to_us, phone.line - 1});
      append_merged(result, {phone.label, to_us, phone.end_us, phone.line});
    } else {
      append_merged(result, {"", phone.start_us, phone.end_us, phone.line - 1});
    }
  }
  return result;
}

}  // namespace

// A window of the recording, from the anchor's frame to the newest, with its long pauses cut: the
// audio the warp hears (`audio`, 16 kHz), which window frame each of its frames is (`kept`), and
// the cuts (window frames [first, second)).
struct LiveSynthesisAligner::Window {
  PcmAudio audio{kFeatureRateHz, {}};
  std::vector<std::size_t> kept;
  std::vector<bool> quiet;  // per kept frame
  std::vector<std::pair<std::size_t, std::size_t>> cuts;

  // The window's sample of the cut audio's sample `s`.
  std::int64_t window_sample(std::int64_t s) const {
    const auto block = static_cast<std::size_t>(s / kHopSamples);
    if (block < kept.size()) return static_cast<std::int64_t>(kept[block]) * kHopSamples + s % kHopSamples;
    return static_cast<std::int64_t>(kept.back()) * kHopSamples +
           (s - static_cast<std::int64_t>(kept.size() - 1) * kHopSamples);
  }
};

LiveSynthesisAligner::LiveSynthesisAligner(const LiveSynthesisOptions& options, std::string source)
    : options_(options), source_(std::move(source)), resampler_(options.sample_rate_hz, kFeatureRateHz) {
  if (options_.sample_rate_hz < 8000 || options_.sample_rate_hz > 48000) {
    throw InputError(source_, 0,
                     "sample rate " + std::to_string(options_.sample_rate_hz) + " Hz is outside 8000-48000");
  }
  if (const auto unknown = unknown_voice_error(options_.synthesis.voice)) throw InputError(source_, 0, *unknown);
  rows_.dimensions = 0;
  queue_words(options_.transcript, "the transcript");
  speak_words_due();
}

LiveSynthesisAligner::~LiveSynthesisAligner() = default;

void LiveSynthesisAligner::append_rendering(std::string_view text, std::string_view what) {
  Synthesis synthesis;
  try {
    synthesis = synthesize(text, options_.synthesis);
  } catch (const InputError& error) {
    throw InputError(source_, 0,
                     std::string(what) + ": cannot be spoken by espeak-ng voice '" + options_.synthesis.voice +
                         "': " + error.message());
  }
  if (synthesis.phonemes.intervals.empty()) return;
  for (const std::string& note : synthesis.notes) notes_.push_back(std::string(what) + ": " + note);
  const bool first = rows_.size() == 0 && rows_base_ == 0;
  const PcmAudio spoken = resample(synthesis.audio, kFeatureRateHz);
  const std::int64_t before_us = first ? kLeadingPaddingUs : 0;
  PcmAudio audio{kFeatureRateHz, std::vector<std::int16_t>(static_cast<std::size_t>(us_sample(before_us)), 0)};
  audio.samples.insert(audio.samples.end(), spoken.samples.begin(), spoken.samples.end());
  audio.samples.resize(audio.samples.size() + static_cast<std::size_t>(us_sample(kTrailingPaddingUs)), 0);

  FeatureStatistics statistics;
  const FeatureFrames frames = mfcc_features(audio, FeatureNormalisation{}, &statistics);
  if (frames.size() == 0) return;
  // The chunk's phones on its own clock, padded with silence and ending where its frames end.
  const std::int64_t end_us = static_cast<std::int64_t>(frames.size()) * kFeatureHopUs;
  LabeledUtterance phones;
  phones.intervals.push_back({"", 0, before_us, 0});
  for (LabeledInterval interval : synthesis.phonemes.intervals) {
    interval.start_us += before_us;
    interval.end_us += before_us;
    if (interval.start_us >= end_us) break;
    interval.end_us = std::min(interval.end_us, end_us);
    append_merged(phones.intervals, interval);
  }
  append_merged(phones.intervals, {"", phones.intervals.back().end_us, end_us, 0});
  if (phones.intervals.front().end_us <= 0) phones.intervals.erase(phones.intervals.begin());
  // Each word's first phone: the first starting where espeak-ng's word starts, or after it (before
  // the stops move to their closures, which moves their starts).
  const std::size_t chunk_words = word_count(text);
  std::vector<std::int64_t> first_phones(chunk_words, -1);
  for (std::size_t w = 0; w < chunk_words && w < synthesis.word_starts_us.size(); ++w) {
    if (synthesis.word_starts_us[w] < 0) continue;
    const std::int64_t start_us = synthesis.word_starts_us[w] + before_us;
    const auto phone = std::find_if(phones.intervals.begin(), phones.intervals.end(),
                                    [&](const LabeledInterval& interval) { return interval.start_us >= start_us; });
    if (phone == phones.intervals.end()) continue;
    first_phones[w] = static_cast<std::int64_t>(phones_base_ + phones_.size()) + (phone - phones.intervals.begin());
  }
  const std::vector<std::int64_t> bursts = detail::move_stop_starts_to_closures(audio, phones);

  // Onto the rendering's clock, after what is there.
  const std::int64_t offset_us = static_cast<std::int64_t>(rows_base_ + rows_.size()) * kFeatureHopUs;
  if (rows_.dimensions == 0) rows_.dimensions = frames.dimensions;
  rows_.values.insert(rows_.values.end(), frames.values.begin(), frames.values.end());
  rows_.level_db.insert(rows_.level_db.end(), frames.level_db.begin(), frames.level_db.end());
  const std::vector<bool> quiet = detail::pause_frames(frames);
  rows_quiet_.insert(rows_quiet_.end(), quiet.begin(), quiet.end());
  for (std::size_t k = 0; k < phones.intervals.size(); ++k) {
    LabeledInterval interval = phones.intervals[k];
    interval.start_us += offset_us;
    interval.end_us += offset_us;
    interval.line = static_cast<int>(words_);
    phones_.push_back(std::move(interval));
    bursts_us_.push_back(bursts[k] + offset_us);
  }
  if (rendering_means_.empty()) {
    const auto dimensions = static_cast<std::size_t>(frames.dimensions);
    rendering_means_.assign(dimensions, 0.0);
    for (std::size_t k = 0; k < frames.size(); ++k)
      for (std::size_t d = 0; d < dimensions; ++d) rendering_means_[d] += statistics.unweighted[k * dimensions + d];
    for (double& mean : rendering_means_) mean /= static_cast<double>(frames.size());
  }
  word_phones_.insert(word_phones_.end(), first_phones.begin(), first_phones.end());
  words_ += chunk_words;
}

void LiveSynthesisAligner::queue_words(std::string_view text, const std::string& what) {
  // A chunk ends after a sentence's end (. ! ? followed by a space) once it holds kChunkWords words.
  std::string chunk;
  std::size_t chunk_words = 0;
  const auto flush = [&] {
    if (chunk_words == 0) return;
    const std::string range =
        "words " + std::to_string(queued_words_ + 1) + "-" + std::to_string(queued_words_ + chunk_words);
    pending_.push_back({chunk, what == "words" ? range : what + " (" + range + ")", chunk_words, queued_words_ + 1,
                        ends_sentence(chunk)});
    queued_words_ += chunk_words;
    chunk.clear();
    chunk_words = 0;
  };
  std::istringstream words{std::string(text)};
  for (std::string word; words >> word;) {
    chunk += (chunk.empty() ? "" : " ") + word;
    ++chunk_words;
    if (ends_sentence(word) && chunk_words >= kChunkWords) flush();
  }
  flush();
}

void LiveSynthesisAligner::speak_words_due(bool ended) {
  while (!pending_.empty()) {
    const std::size_t rendered = rows_base_ + rows_.size();
    if (rendered > next_phone_row() + kRowsSpokenAhead) return;
    // A sentence whose words come a few at a time (a TTS's word marks) is spoken whole once its end
    // has come: each part spoken alone would be rendered as a sentence of its own. Its words wait
    // while the rendering reaches kRowsHeldAhead past the row of the newest audio (the anchor's
    // row and the audio heard since).
    const auto end =
        std::find_if(pending_.begin(), pending_.end(), [](const PendingWords& words) { return words.ends_sentence; });
    const std::size_t newest_row =
        next_phone_row() + static_cast<std::size_t>(std::max<std::int64_t>(0, heard_us_ - final_us_) / kFeatureHopUs);
    if (end == pending_.end() && !ended && rendered > newest_row + kRowsHeldAhead) return;
    const auto take = static_cast<std::size_t>(end == pending_.end() ? pending_.size() : end - pending_.begin() + 1);
    PendingWords words = std::move(pending_.front());
    pending_.pop_front();
    for (std::size_t taken = 1; taken < take; ++taken) {
      words.text += " " + pending_.front().text;
      words.count += pending_.front().count;
      pending_.pop_front();
    }
    if (take > 1 && words.what.rfind("words ", 0) == 0) {
      words.what =
          "words " + std::to_string(words.first_word) + "-" + std::to_string(words.first_word + words.count - 1);
    }
    speak(std::move(words));
  }
}

void LiveSynthesisAligner::speak(PendingWords words) {
  std::vector<std::string> tokens;
  std::istringstream split{words.text};
  for (std::string token; split >> token;) tokens.push_back(std::move(token));
  // The unheard rest of an open sentence is spoken again with the words that continue it: from its
  // first word whose first phone the anchor has not reached, the rendering is cut and that word on
  // is spoken anew, so the sentence is rendered as one (one intonation, no pause or falling end
  // before the new words) wherever the speech has not got to yet.
  std::string what = std::move(words.what);
  for (std::size_t k = 0; k < open_sentence_.size(); ++k) {
    const std::size_t word = open_sentence_first_ + k;
    if (word < word_phones_base_) continue;
    const std::int64_t phone = word_phones_[word - word_phones_base_];
    if (phone < static_cast<std::int64_t>(std::max(next_phone_, phones_base_))) continue;
    if (open_sentence_.size() - k > kMostWordsSpokenAgain) break;
    cut_rendering_at(word, static_cast<std::size_t>(phone));
    tokens.insert(tokens.begin(), open_sentence_.begin() + static_cast<std::ptrdiff_t>(k), open_sentence_.end());
    open_sentence_.resize(k);
    ++respoken_;
    what = "words " + std::to_string(word + 1) + "-" + std::to_string(word + tokens.size());
    break;
  }
  std::string text;
  for (const std::string& token : tokens) text += (text.empty() ? "" : " ") + token;
  if (open_sentence_.empty()) open_sentence_first_ = words_;
  append_rendering(text, what);
  // The sentence still open after these words: those after the last sentence's end.
  open_sentence_.insert(open_sentence_.end(), tokens.begin(), tokens.end());
  const auto last_end = std::find_if(open_sentence_.rbegin(), open_sentence_.rend(),
                                     [](const std::string& word) { return ends_sentence(word); });
  if (last_end != open_sentence_.rend()) {
    const auto closed = static_cast<std::size_t>(open_sentence_.rend() - last_end);
    open_sentence_.erase(open_sentence_.begin(), open_sentence_.begin() + static_cast<std::ptrdiff_t>(closed));
    open_sentence_first_ += closed;
  }
  // A word espeak-ng spoke nothing of, or the rendering cut short, leaves words_ behind the tokens:
  // the open sentence is then given up (its words are spoken, just not again).
  if (open_sentence_first_ + open_sentence_.size() != words_) open_sentence_.clear();
}

void LiveSynthesisAligner::cut_rendering_at(std::size_t word, std::size_t phone) {
  const std::size_t row = std::max(phone_row(phone), rows_base_);
  const auto dimensions = static_cast<std::size_t>(rows_.dimensions);
  const std::size_t keep_rows = row - rows_base_;
  rows_.values.resize(keep_rows * dimensions);
  rows_.level_db.resize(keep_rows);
  rows_quiet_.resize(keep_rows);
  phones_.resize(phone - phones_base_);
  bursts_us_.resize(phone - phones_base_);
  // The phone before the cut ends where the rows do (a phone left without a row is dropped).
  const auto end_us = static_cast<std::int64_t>(row) * kFeatureHopUs;
  while (!phones_.empty() && phones_.back().start_us >= end_us) {
    phones_.pop_back();
    bursts_us_.pop_back();
  }
  if (!phones_.empty()) phones_.back().end_us = end_us;
  word_phones_.resize(word - word_phones_base_);
  words_ = word;
}

std::size_t LiveSynthesisAligner::next_phone_row() const { return phone_row(next_phone_); }

std::size_t LiveSynthesisAligner::phone_row(std::size_t phone) const {
  if (phone >= phones_base_ + phones_.size()) return rows_base_ + rows_.size();
  return static_cast<std::size_t>(phones_[phone - phones_base_].start_us / kFeatureHopUs);
}

void LiveSynthesisAligner::add_words(std::string_view text) {
  queue_words(text, "words");
  speak_words_due();
}

void LiveSynthesisAligner::add_timed_words(std::span<const TimedWord> words) {
  // Checked as the English recogniser checks them, all before any is added.
  std::string text;
  std::vector<TimedStart> timed;
  std::size_t word = queued_words_;
  std::int64_t previous_us = last_timed_us_;
  for (const TimedWord& timed_word : words) {
    const std::string number = "timed word " + std::to_string(word + 1) + " '" + timed_word.text + "'";
    const bool has_letters = std::any_of(timed_word.text.begin(), timed_word.text.end(), [](char c) {
      return static_cast<unsigned char>(c) >= 0x80 || std::isalnum(static_cast<unsigned char>(c)) != 0;
    });
    if (!has_letters) throw InputError(source_, 0, number + " has no letters or digits");
    if (timed_word.start_us < previous_us) {
      throw InputError(source_, 0,
                       number + " starts at " + std::to_string(timed_word.start_us) +
                           " us, before the word before it (" + std::to_string(previous_us) +
                           " us): timed words come in the order they are spoken, on the stream's clock");
    }
    previous_us = timed_word.start_us;
    timed.push_back({word, timed_word.start_us});
    word += word_count(timed_word.text);
    text += (text.empty() ? "" : " ") + timed_word.text;
  }
  last_timed_us_ = previous_us;
  timed_words_.insert(timed_words_.end(), timed.begin(), timed.end());
  add_words(text);
}

std::size_t LiveSynthesisAligner::words_ahead() const {
  if (next_phone_ >= phones_base_ + phones_.size()) return 0;
  std::size_t pending = 0;
  for (const PendingWords& words : pending_) pending += words.count;
  const auto reached = static_cast<std::size_t>(phones_[next_phone_ - phones_base_].line);
  return (words_ > reached ? words_ - reached : 0) + pending;
}

void LiveSynthesisAligner::push(std::span<const std::int16_t> samples) {
  if (finished_) return;
  samples_in_ += static_cast<std::int64_t>(samples.size());
  resampled_.clear();
  resampler_.push(samples, resampled_);
  audio_.insert(audio_.end(), resampled_.begin(), resampled_.end());
  heard_us_ = samples_in_ * 1'000'000 / options_.sample_rate_hz;
  const std::size_t frames_before = levels_db_.size();
  measure_new_frames();
  if (levels_db_.size() > frames_before) update(false);
  cover_heard_with_guess();
}

void LiveSynthesisAligner::cover_heard_with_guess() {
  std::erase_if(guess_, [&](const LabeledInterval& phone) { return phone.end_us <= final_us_; });
  if (guess_.empty()) {
    if (heard_us_ > final_us_) guess_.push_back({"", final_us_, heard_us_, 0});
    return;
  }
  guess_.front().start_us = final_us_;
  guess_.back().end_us = heard_us_;
  std::erase_if(guess_, [](const LabeledInterval& phone) { return phone.end_us <= phone.start_us; });
}

void LiveSynthesisAligner::finish() {
  if (finished_) return;
  resampled_.clear();
  resampler_.finish(resampled_);
  audio_.insert(audio_.end(), resampled_.begin(), resampled_.end());
  measure_new_frames();
  update(true);
  finalise_silence_until(heard_us_);  // what the warp could not reach (too little audio to warp)
  guess_.clear();
  finished_ = true;
}

void LiveSynthesisAligner::measure_new_frames() {
  const auto available = static_cast<std::int64_t>(audio_.size());
  for (auto k = static_cast<std::int64_t>(levels_db_.size()); k * kHopSamples + kWindowSamples <= available; ++k) {
    double energy = 0.0;
    for (std::int64_t i = 0; i < kWindowSamples; ++i) {
      const double sample = audio_[static_cast<std::size_t>(k * kHopSamples + i)] / 32768.0;
      energy += sample * sample;
    }
    const double level = 10.0 * std::log10(std::max(energy / static_cast<double>(kWindowSamples), 1e-20));
    levels_db_.push_back(level);
    loudest_level_db_ = std::max(loudest_level_db_, level);
  }
}

void LiveSynthesisAligner::finalise_silence_until(std::int64_t end_us) {
  if (end_us <= final_us_) return;
  append_merged(final_, {"", final_us_, end_us, static_cast<int>(next_phone_) - 1});
  move_anchor_to(end_us, next_phone_);
}

void LiveSynthesisAligner::move_anchor_to(std::int64_t end_us, std::size_t next_phone) {
  final_us_ = end_us;
  next_phone_ = std::max(next_phone_, next_phone);
  const std::int64_t base = us_sample(end_us) / kHopSamples * kHopSamples;
  if (base > audio_base_sample_) {
    const auto dropped = static_cast<std::size_t>(base - audio_base_sample_);
    const std::size_t dropped_frames = dropped / static_cast<std::size_t>(kHopSamples);
    audio_.erase(audio_.begin(), audio_.begin() + static_cast<std::ptrdiff_t>(std::min(dropped, audio_.size())));
    levels_db_.erase(levels_db_.begin(),
                     levels_db_.begin() + static_cast<std::ptrdiff_t>(std::min(dropped_frames, levels_db_.size())));
    audio_base_sample_ = base;
  }
  drop_behind_anchor();
}

void LiveSynthesisAligner::drop_behind_anchor() {
  if (next_phone_ <= phones_base_ || next_phone_ - phones_base_ > phones_.size()) return;
  const std::size_t next = next_phone_ - phones_base_;
  const std::size_t row = next_phone_row();
  if (row < rows_base_ + kDropRowsAfter * 2 || next == 0) return;
  const std::size_t drop_rows = row - kDropRowsAfter - rows_base_;
  const auto dimensions = static_cast<std::size_t>(rows_.dimensions);
  rows_.values.erase(rows_.values.begin(), rows_.values.begin() + static_cast<std::ptrdiff_t>(drop_rows * dimensions));
  rows_.level_db.erase(rows_.level_db.begin(), rows_.level_db.begin() + static_cast<std::ptrdiff_t>(drop_rows));
  rows_quiet_.erase(rows_quiet_.begin(), rows_quiet_.begin() + static_cast<std::ptrdiff_t>(drop_rows));
  rows_base_ += drop_rows;
  phones_.erase(phones_.begin(), phones_.begin() + static_cast<std::ptrdiff_t>(next));
  bursts_us_.erase(bursts_us_.begin(), bursts_us_.begin() + static_cast<std::ptrdiff_t>(next));
  phones_base_ += next;
  // The words whose first phone went with them (and the words before those), and their times.
  std::size_t dropped_words = 0;
  while (dropped_words < word_phones_.size() && word_phones_[dropped_words] < static_cast<std::int64_t>(phones_base_)) {
    ++dropped_words;
  }
  word_phones_.erase(word_phones_.begin(), word_phones_.begin() + static_cast<std::ptrdiff_t>(dropped_words));
  word_phones_base_ += dropped_words;
  std::erase_if(timed_words_, [&](const TimedStart& timed) { return timed.word < word_phones_base_; });
}

std::int64_t LiveSynthesisAligner::frame_us(std::size_t frame) const {
  return sample_us(audio_base_sample_ + static_cast<std::int64_t>(frame) * kHopSamples);
}

LiveSynthesisAligner::Window LiveSynthesisAligner::cut_window(std::size_t from, std::size_t to,
                                                              double quiet_below_db) const {
  Window window;
  const auto cut_frames = static_cast<std::size_t>(options_.pause_cut_us / kFeatureHopUs);
  for (std::size_t k = from; k < to;) {
    if (levels_db_[k] >= quiet_below_db) {
      window.kept.push_back(k);
      window.quiet.push_back(false);
      ++k;
      continue;
    }
    std::size_t end = k;
    while (end < to && levels_db_[end] < quiet_below_db) ++end;
    const std::size_t head = k == from ? 0 : kPauseHeadFrames;
    if (end - k > cut_frames && end - k > head + kPauseTailFrames) {
      window.cuts.emplace_back(k + head, end - kPauseTailFrames);
      for (std::size_t f = k; f < k + head; ++f) window.kept.push_back(f);
      for (std::size_t f = end - kPauseTailFrames; f < end; ++f) window.kept.push_back(f);
    } else {
      for (std::size_t f = k; f < end; ++f) window.kept.push_back(f);
    }
    window.quiet.resize(window.kept.size(), true);
    k = end;
  }
  for (const std::size_t f : window.kept) {
    const auto first = audio_.begin() + static_cast<std::ptrdiff_t>(f * kHopSamples);
    window.audio.samples.insert(window.audio.samples.end(), first, first + kHopSamples);
  }
  const auto tail_from = static_cast<std::size_t>((window.kept.back() + 1) * kHopSamples);
  const std::size_t tail_end =
      std::min(audio_.size(), tail_from + static_cast<std::size_t>(kWindowSamples - kHopSamples));
  window.audio.samples.insert(window.audio.samples.end(), audio_.begin() + static_cast<std::ptrdiff_t>(tail_from),
                              audio_.begin() + static_cast<std::ptrdiff_t>(tail_end));
  return window;
}

std::optional<std::size_t> LiveSynthesisAligner::timed_phone_after(std::int64_t from_us) {
  const auto first = std::lower_bound(timed_words_.begin(), timed_words_.end(), from_us,
                                      [](const TimedStart& timed, std::int64_t us) { return timed.start_us < us; });
  for (auto timed = first; timed != timed_words_.end(); ++timed) {
    const std::size_t word = timed->word;
    while (word >= words_ && !pending_.empty()) {
      PendingWords words = std::move(pending_.front());
      pending_.pop_front();
      speak(std::move(words));
    }
    if (word < word_phones_base_ || word - word_phones_base_ >= word_phones_.size()) continue;
    const std::int64_t phone = word_phones_[word - word_phones_base_];
    if (phone >= static_cast<std::int64_t>(phones_base_) &&
        phone < static_cast<std::int64_t>(phones_base_ + phones_.size())) {
      return static_cast<std::size_t>(phone);
    }
  }
  return std::nullopt;
}

bool LiveSynthesisAligner::find_split(std::size_t frames, double quiet_below_db, Split& split) {
  const auto cut_frames = static_cast<std::size_t>(options_.pause_cut_us / kFeatureHopUs);
  for (std::size_t k = 0; k < frames;) {
    if (levels_db_[k] >= quiet_below_db) {
      ++k;
      continue;
    }
    std::size_t end = k;
    while (end < frames && levels_db_[end] < quiet_below_db) ++end;
    if (end == frames) break;  // a pause still going on
    // A pause the anchor is in began where it was seen beginning (or, not seen, at the anchor).
    std::int64_t pause_from_us = frame_us(k);
    if (k == 0) {
      const auto after = std::upper_bound(pause_starts_us_.begin(), pause_starts_us_.end(), pause_from_us);
      if (after != pause_starts_us_.begin()) pause_from_us = *(after - 1);
    }
    const std::size_t head = k == 0 ? 0 : kPauseHeadFrames;
    const bool cut = end - k > cut_frames && end - k > head + kPauseTailFrames;
    const bool long_before = k == 0 && frame_us(end) - pause_from_us > options_.pause_cut_us;
    // The stream's first pause is not one: its first speech starts at the first word, as the anchor does.
    if ((cut || long_before) && pause_from_us > 0) {
      if (const auto phone = timed_phone_after((pause_from_us + frame_us(end)) / 2)) {
        // From the rendering's pause before the word where it has one: the pause's last frames,
        // kept before the speech, have a pause to match, as at the stream's start.
        const bool pause_before = *phone > phones_base_ && phones_[*phone - 1 - phones_base_].label.empty();
        const std::size_t silence_from = k + head;
        split = {silence_from, std::max(silence_from, end - std::min(end, kPauseTailFrames)),
                 pause_before ? *phone - 1 : *phone};
        return true;
      }
    }
    k = end;
  }
  return false;
}

std::vector<LabeledInterval> LiveSynthesisAligner::hear(const Window& window, std::size_t first_phone,
                                                        std::int64_t start_us, std::int64_t end_us) {
  // The window's features, normalised by the stream so far; the new frames' into the stream's means.
  FeatureStatistics statistics;
  const FeatureFrames columns = mfcc_features(window.audio, normalisation_, &statistics);
  if (columns.size() < 2) return {};
  const auto dimensions = static_cast<std::size_t>(columns.dimensions);
  if (mean_sums_.empty()) mean_sums_.assign(dimensions, 0.0);
  const auto window_first_frame = static_cast<std::size_t>(audio_base_sample_ / kHopSamples);
  for (std::size_t c = 0; c < columns.size() && c < window.kept.size(); ++c) {
    const std::size_t frame = window_first_frame + window.kept[c];
    if (frame < counted_frames_ || window.quiet[c]) continue;
    for (std::size_t d = 0; d < dimensions; ++d) mean_sums_[d] += statistics.unweighted[c * dimensions + d];
    counted_frames_ = frame + 1;
    ++mean_count_;
  }
  normalisation_.loudest_band_power = std::max(normalisation_.loudest_band_power, statistics.loudest_band_power);
  normalisation_.means.assign(dimensions, 0.0);
  for (std::size_t d = 0; d < dimensions; ++d) {
    normalisation_.means[d] =
        (mean_sums_[d] + kPriorFrames * rendering_means_[d]) / (static_cast<double>(mean_count_) + kPriorFrames);
  }

  // The open-ended warp from the phone's row.
  const std::size_t phones_end = phones_base_ + phones_.size();
  const std::size_t first_row = phone_row(first_phone);
  const std::size_t rows_ahead = rows_base_ + rows_.size() > first_row ? rows_base_ + rows_.size() - first_row : 0;
  if (rows_ahead < 2 || first_phone >= phones_end) return {};
  const std::size_t row0 = first_row - rows_base_;
  const std::size_t row_count = std::min(rows_ahead, kRowsPerColumn * columns.size() + kExtraRows);
  std::vector<bool> columns_quiet(window.quiet.begin(),
                                  window.quiet.begin() + static_cast<std::ptrdiff_t>(columns.size()));
  const WarpPath path = open_end_warp(rows_, rows_quiet_, row0, row_count, columns, columns_quiet, options_.stretch);

  // The rendering's phones the path reaches, on the window's clock (row0's start is 0).
  const std::int64_t origin_us = static_cast<std::int64_t>(first_row) * kFeatureHopUs;
  const std::int64_t reached_us = static_cast<std::int64_t>(path.first.size()) * kFeatureHopUs;
  std::vector<LabeledInterval> phones;
  std::vector<std::int64_t> bursts;
  for (std::size_t p = first_phone; p < phones_end; ++p) {
    LabeledInterval phone = phones_[p - phones_base_];
    phone.start_us = std::max<std::int64_t>(0, phone.start_us - origin_us);
    if (!phones.empty() && phone.start_us >= reached_us) break;
    phone.end_us = std::min(phone.end_us - origin_us, reached_us);
    phone.line = static_cast<int>(p);
    phones.push_back(std::move(phone));
    bursts.push_back(bursts_us_[p - phones_base_] - origin_us);
  }
  const std::int64_t window_end_us = window.audio.duration_us();
  std::vector<std::int64_t> bounds =
      detail::carried_bounds(path, phones, bursts, window_end_us, columns_quiet, window.audio);
  start_bilabial_nasals_at_murmur(bounds, phones, formant_band_levels_db(window.audio, 10'000, 1'000));
  LabeledUtterance carried;
  for (std::size_t k = 0; k < phones.size(); ++k) {
    if (bounds[k + 1] > bounds[k])
      carried.intervals.push_back({phones[k].label, bounds[k], bounds[k + 1], phones[k].line});
  }
  if (carried.intervals.empty()) return {};
  if (options_.refine_closures) detail::refine_lip_phones(window.audio, carried, options_.refiner);

  // Back onto the stream's clock, with the cut pauses as silence.
  const auto stream_us = [&](std::int64_t window_us) {
    return sample_us(audio_base_sample_ + window.window_sample(us_sample(window_us)));
  };
  std::vector<LabeledInterval> heard;
  for (const LabeledInterval& interval : carried.intervals) {
    const std::int64_t start = heard.empty() ? start_us : std::max(stream_us(interval.start_us), start_us);
    const std::int64_t end =
        &interval == &carried.intervals.back() ? end_us : std::max(stream_us(interval.end_us), start);
    append_merged(heard, {interval.label, start, end, interval.line});
  }
  for (const auto& [cut_first, cut_end] : window.cuts)
    heard = with_silence(heard, frame_us(cut_first), frame_us(cut_end));
  return heard;
}

void LiveSynthesisAligner::update(bool ended) {
  guess_.clear();
  speak_words_due(ended);
  const std::int64_t commit_limit_us =
      ended ? std::numeric_limits<std::int64_t>::max() : heard_us_ - options_.commit_us;
  const std::size_t frames = levels_db_.size();
  const double quiet_below_db = std::max(loudest_level_db_ - kSpeechRangeDb, kQuietDbfs);
  // With timed words, the speech after a pause may be placed by them (the top of the header).
  Split split;
  const bool splits = !timed_words_.empty() && frames >= 3 && find_split(frames, quiet_below_db, split);
  const int line_before_split = static_cast<int>(split.phone) - 1;  // the split silence's line
  if (frames > 0) {
    // The starts of the pauses seen beginning: of the one the anchor may be in, and those after it.
    std::size_t first_quiet = frames;
    while (first_quiet > 0 && levels_db_[first_quiet - 1] < quiet_below_db) --first_quiet;
    if (first_quiet > 0 && first_quiet < frames &&
        (pause_starts_us_.empty() || pause_starts_us_.back() < frame_us(first_quiet))) {
      pause_starts_us_.push_back(frame_us(first_quiet));
    }
    const auto after = std::upper_bound(pause_starts_us_.begin(), pause_starts_us_.end(), frame_us(0));
    if (after - pause_starts_us_.begin() > 1) pause_starts_us_.erase(pause_starts_us_.begin(), after - 1);
  }
  const std::size_t phones_end = phones_base_ + phones_.size();
  // The rendering's rows from the next phone on.
  const std::size_t first_row = next_phone_row();
  const std::size_t rows_ahead = rows_base_ + rows_.size() > first_row ? rows_base_ + rows_.size() - first_row : 0;
  if (!splits && (rows_ahead < 2 || next_phone_ >= phones_end)) {
    // Nothing of the transcript to hear: silence (final once it is commit_us old).
    if (!said_silence_ && heard_us_ > final_us_ + options_.commit_us) {
      said_silence_ = true;
      notes_.push_back(std::string(words_ == 0 ? "audio before the transcript's first word"
                                               : "audio after the transcript's last word") +
                       " is shown as silence: voice '" + options_.synthesis.voice +
                       "' is heard only against its words; send them (settings.transcript, ListenWords)");
    }
    finalise_silence_until(ended ? heard_us_ : commit_limit_us);
    return;
  }
  said_silence_ = false;
  if (frames < 3) {
    if (ended) finalise_silence_until(heard_us_);
    return;
  }

  // The window's phones: from the anchor, or, split at a pause, before it and from the timed word
  // after it, the pause silent between (its silence carries the line of the phone before the word).
  std::vector<LabeledInterval> before_split;
  std::size_t split_at = 0;   // heard's first phone from the split's silence on
  std::size_t last_from = 0;  // the window frame the last part starts at
  std::int64_t last_from_us = final_us_;
  if (splits) {
    if (split.silence_from > 0) {
      before_split =
          hear(cut_window(0, split.silence_from, quiet_below_db), next_phone_, final_us_, frame_us(split.silence_from));
    }
    last_from = split.speech_from;
    last_from_us = std::max(final_us_, frame_us(last_from));
    const std::int64_t silence_from_us = before_split.empty() ? final_us_ : before_split.back().end_us;
    split_at = before_split.size();
    if (last_from_us > silence_from_us) {
      before_split.push_back({"", silence_from_us, last_from_us, line_before_split});
    }
  }
  const Window window = cut_window(last_from, frames, quiet_below_db);
  std::vector<LabeledInterval> heard = hear(window, splits ? split.phone : next_phone_, last_from_us, heard_us_);
  if (heard.empty()) {
    if (!splits) return;
    if (heard_us_ > last_from_us) heard.push_back({"", last_from_us, heard_us_, line_before_split});
  }
  // A pause still going on is silence up to kShownQuietUs before the newest audio (the warp matched
  // its frames to whatever comes next in the rendering: the next word's first sound), and final as
  // far as that once it reaches back to the commit delay.
  std::int64_t pause_end_us = -1;
  if (!ended && !window.quiet.empty() && window.quiet.back()) {
    std::size_t first_quiet = frames;
    while (first_quiet > 0 && levels_db_[first_quiet - 1] < quiet_below_db) --first_quiet;
    const std::int64_t from =
        frame_us(first_quiet) + (first_quiet == 0 ? 0 : static_cast<std::int64_t>(kPauseHeadFrames) * kFeatureHopUs);
    const std::int64_t to = heard_us_ - kShownQuietUs;
    if (to > from) {
      heard = with_silence(heard, from, to);
      if (from <= commit_limit_us) pause_end_us = to;
    }
  }
  if (splits) heard.insert(heard.begin(), before_split.begin(), before_split.end());

  // The phones commit_us old are final, and the anchor moves past them.
  std::size_t final_count = 0;
  while (final_count < heard.size() && (ended || final_count + 1 < heard.size()) &&
         heard[final_count].end_us <= commit_limit_us) {
    ++final_count;
  }
  if (pause_end_us > 0) {
    for (std::size_t k = final_count; k < heard.size(); ++k) {
      if (!heard[k].label.empty() || heard[k].end_us < pause_end_us) continue;
      const LabeledInterval rest{"", pause_end_us, heard[k].end_us, heard[k].line};
      heard[k].end_us = pause_end_us;
      if (rest.end_us > rest.start_us) heard.insert(heard.begin() + static_cast<std::ptrdiff_t>(k) + 1, rest);
      final_count = k + 1;
      break;
    }
  }
  if (final_count > 0) {
    // Past a split, the next phone follows the phones after it alone (it may lie behind the anchor's).
    const bool past_split = splits && final_count > split_at;
    int last_line = past_split ? line_before_split : static_cast<int>(next_phone_) - 1;
    for (std::size_t k = 0; k < final_count; ++k) {
      append_merged(final_, heard[k]);
      if (!past_split || k >= split_at) last_line = std::max(last_line, heard[k].line);
    }
    const int next_phone = last_line + 1;
    if (past_split) {
      next_phone_ = static_cast<std::size_t>(next_phone);
      // That pause is behind the anchor now (its last frames, in the window, are no pause to split at).
      const std::int64_t anchor_us = heard[final_count - 1].end_us;
      std::erase_if(pause_starts_us_, [&](std::int64_t start_us) { return start_us <= anchor_us; });
    }
    move_anchor_to(heard[final_count - 1].end_us, static_cast<std::size_t>(next_phone));
  }
  for (std::size_t k = final_count; k < heard.size(); ++k) append_merged(guess_, heard[k]);
}

std::vector<LabeledInterval> LiveSynthesisAligner::take_final() {
  const bool hold_last = !finished_ && !final_.empty() && final_.back().label.empty();
  std::vector<LabeledInterval> taken(final_.begin(), final_.end() - (hold_last ? 1 : 0));
  final_.erase(final_.begin(), final_.end() - (hold_last ? 1 : 0));
  for (LabeledInterval& phone : taken) phone.line = 0;
  return taken;
}

std::vector<LabeledInterval> LiveSynthesisAligner::guess() const {
  std::vector<LabeledInterval> guess = final_;
  guess.insert(guess.end(), guess_.begin(), guess_.end());
  for (LabeledInterval& phone : guess) phone.line = 0;
  return guess;
}

std::vector<std::string> LiveSynthesisAligner::take_notes() {
  std::vector<std::string> taken;
  taken.swap(notes_);
  return taken;
}

}  // namespace lipsync::speech
