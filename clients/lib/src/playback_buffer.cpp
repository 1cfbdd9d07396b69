// Interpolating playback of a frame stream against a media clock (see playback_buffer.hpp).
#include "lipsync/client/playback_buffer.hpp"

#include <algorithm>
#include <stdexcept>

namespace lipsync::client {

PlaybackBuffer::PlaybackBuffer(std::size_t channel_count, std::size_t capacity_frames)
    : channel_count_(channel_count), capacity_frames_(capacity_frames) {
  if (channel_count == 0) throw std::invalid_argument("PlaybackBuffer needs at least one channel");
  if (capacity_frames < 2) throw std::invalid_argument("PlaybackBuffer needs room for at least two frames");
}

std::optional<std::int64_t> PlaybackBuffer::newest_frame_us() const {
  if (times_us_.empty()) return std::nullopt;
  return times_us_.back();
}

bool PlaybackBuffer::push(std::int64_t t_us, std::span<const float> values) {
  if (values.size() != channel_count_ || (!times_us_.empty() && t_us <= times_us_.back())) {
    ++stats_.frames_rejected;
    return false;
  }
  if (times_us_.size() == capacity_frames_) {
    drop_front();
    ++stats_.frames_dropped;
  }
  times_us_.push_back(t_us);
  values_.insert(values_.end(), values.begin(), values.end());
  ++stats_.frames_pushed;
  return true;
}

bool PlaybackBuffer::push(std::int64_t t_us, std::span<const float> values, std::int64_t arrival_clock_us) {
  if (!push(t_us, values)) return false;
  if (utterance_zero_us_) {
    const std::int64_t lateness_us = arrival_clock_us - (*utterance_zero_us_ + playout_offset_us_ + t_us);
    stats_.last_lateness_us = lateness_us;
    stats_.max_lateness_us = std::max(stats_.max_lateness_us.value_or(lateness_us), lateness_us);
  }
  return true;
}

void PlaybackBuffer::expect_release_delay(std::int64_t release_delay_us, std::int64_t margin_us) {
  release_delay_us_ = std::max<std::int64_t>(0, release_delay_us);
  release_margin_us_ = std::max<std::int64_t>(0, margin_us);
}

void PlaybackBuffer::note_batch(std::int64_t first_t_us, std::int64_t release_lag_us, std::int64_t arrival_clock_us) {
  stats_.max_release_lag_us = std::max(stats_.max_release_lag_us, release_lag_us);
  if (!utterance_zero_us_ || release_delay_us_ == 0) return;
  // When the producer's input was at utterance time 0, on this clock: the batch
  // left `release_lag_us` after the input reached first_t_us + lag, and the
  // network only adds to that, so the earliest estimate is the best one (a
  // replayed batch arrives late and estimates late; live ones correct it).
  const std::int64_t input_zero_us = arrival_clock_us - first_t_us - release_lag_us;
  input_zero_us_ = std::min(input_zero_us_.value_or(input_zero_us), input_zero_us);
  const std::int64_t wait_us = std::max(release_delay_us_, stats_.max_release_lag_us);
  playout_offset_us_ = std::max<std::int64_t>(0, *input_zero_us_ + wait_us + release_margin_us_ - *utterance_zero_us_);
}

PlaybackSample PlaybackBuffer::sample(std::int64_t clock_us, std::span<float> out) {
  return sample_utterance(clock_us - utterance_zero_us_.value_or(clock_us) - playout_offset_us_, out);
}

PlaybackSample PlaybackBuffer::sample_utterance(std::int64_t utterance_us, std::span<float> out) {
  PlaybackSample result;
  ++stats_.samples;
  if (times_us_.empty() && !last_sample_us_) {
    // Nothing shown yet, so nothing to stay ahead of: the playout offset may
    // still move the play position back before the first frame arrives.
    result.utterance_us = utterance_us;
    return result;
  }
  if (last_sample_us_ && utterance_us < *last_sample_us_) {
    utterance_us = *last_sample_us_;
    result.clamped = true;
    ++stats_.clamped_samples;
  }
  last_sample_us_ = utterance_us;
  result.utterance_us = utterance_us;
  if (times_us_.empty()) return result;

  const auto copy_frame = [&](std::size_t frame) {
    const auto first = values_.begin() + static_cast<std::ptrdiff_t>(frame * channel_count_);
    std::copy_n(first, std::min(channel_count_, out.size()), out.begin());
  };
  result.lead_us = times_us_.back() - utterance_us;

  if (utterance_us < times_us_.front()) {
    result.state = SampleState::before_first;
    copy_frame(0);
    return result;
  }
  if (utterance_us > times_us_.back()) {
    result.state = finished_ ? SampleState::ended : SampleState::underrun;
    if (!finished_) {
      ++stats_.underruns;
      stats_.max_behind_us = std::max(stats_.max_behind_us, -result.lead_us);
    }
    while (times_us_.size() > 1) drop_front();
    copy_frame(0);
    return result;
  }

  // The last frame at or before utterance_us; everything before it is no longer needed.
  const auto after = std::upper_bound(times_us_.begin(), times_us_.end(), utterance_us);
  const auto before_count = static_cast<std::size_t>(after - times_us_.begin()) - 1;
  for (std::size_t i = 0; i < before_count; ++i) drop_front();

  result.state = SampleState::playing;
  stats_.min_lead_us = std::min(stats_.min_lead_us.value_or(result.lead_us), result.lead_us);
  if (times_us_.size() == 1 || times_us_.front() == utterance_us) {
    copy_frame(0);
    return result;
  }
  const double t0 = static_cast<double>(times_us_[0]);
  const double t1 = static_cast<double>(times_us_[1]);
  const auto weight = static_cast<float>((static_cast<double>(utterance_us) - t0) / (t1 - t0));
  const std::size_t count = std::min(channel_count_, out.size());
  for (std::size_t c = 0; c < count; ++c) {
    const float v0 = values_[c];
    const float v1 = values_[channel_count_ + c];
    out[c] = v0 + weight * (v1 - v0);
  }
  return result;
}

void PlaybackBuffer::drop_front() {
  times_us_.pop_front();
  values_.erase(values_.begin(), values_.begin() + static_cast<std::ptrdiff_t>(channel_count_));
}

}  // namespace lipsync::client
