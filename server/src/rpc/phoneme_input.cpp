// One phoneme at a time through the SegmentBuilder and the limits (phoneme_input.hpp).
#include "phoneme_input.hpp"

#include <string>

#include "lipsync/error.hpp"

namespace lipsync::server {

grpc::Status too_many_phonemes(std::size_t limit) {
  return {grpc::StatusCode::RESOURCE_EXHAUSTED, "the utterance has more than " + std::to_string(limit) +
                                                    " phonemes (--max-phonemes=" + std::to_string(limit) + ")"};
}

PhonemeInput::PhonemeInput(const Plan& plan, const ServerConfig& config)
    : config_(config), builder_(*plan.model->model, *plan.phone_set, kStreamSource, plan.engine.segments) {}

grpc::Status PhonemeInput::push(const v1::Phoneme& phoneme, std::vector<Segment>& out) {
  if (count_ >= config_.max_phonemes) return too_many_phonemes(config_.max_phonemes);
  const int index = static_cast<int>(++count_);
  try {
    builder_.push(phoneme.label(), phoneme.start_us(), phoneme.end_us(), index, out);
  } catch (const InputError& error) {
    return invalid(error.what());
  }
  newest_start_us_ = phoneme.start_us();
  if (builder_.end_us() > config_.max_utterance_ms * 1000) {
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            std::string(kStreamSource) + ":" + std::to_string(index) + ": the utterance reaches " +
                std::to_string(builder_.end_us()) +
                " us, longer than --max-utterance-ms=" + std::to_string(config_.max_utterance_ms)};
  }
  // OK: a default Status, not a copy of Status::OK, which copies its two strings (per phoneme).
  return grpc::Status();
}

}  // namespace lipsync::server
