// Speak's synthesis thread (speech_thread.hpp).
#include "speech_thread.hpp"

#include <boost/asio/post.hpp>
#include <string>

namespace lipsync::server {

SpeechThread::SpeechThread() = default;

SpeechThread::~SpeechThread() { pool_.join(); }

grpc::Status SpeechThread::post(std::function<void()> job) {
  if (++calls_ > kMaxSpeakCalls) {
    --calls_;
    return {grpc::StatusCode::RESOURCE_EXHAUSTED,
            "the speech synthesiser is busy: " + std::to_string(kMaxSpeakCalls) +
                " Speak calls already wait for it (espeak-ng speaks one text at a time)"};
  }
  boost::asio::post(pool_, [this, job = std::move(job)] {
    job();
    --calls_;
  });
  return grpc::Status::OK;
}

}  // namespace lipsync::server
