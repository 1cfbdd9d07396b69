#include "outbox.hpp"

#include <grpcpp/impl/codegen/proto_utils.h>

#include <stdexcept>

namespace lipsync::server {

const grpc::ByteBuffer& OutgoingMessage::bytes() const {
  if (encoded_.load(std::memory_order_acquire)) return bytes_;
  std::lock_guard lock(encode_mutex_);
  if (!encoded_.load(std::memory_order_relaxed)) {
    bool own_buffer = false;
    const grpc::Status status = grpc::SerializationTraits<v1::TrackMessage>::Serialize(message_, &bytes_, &own_buffer);
    // Serialising an in-memory message only fails beyond protobuf's 2 GiB limit,
    // which the server's batch and replay limits keep far away.
    if (!status.ok()) throw std::runtime_error("cannot serialise a TrackMessage: " + status.error_message());
    encoded_.store(true, std::memory_order_release);
  }
  return bytes_;
}

Outbox::Outbox(OutboxTarget& target, std::size_t max_frames, std::string overflow_message)
    : target_(target), max_frames_(max_frames), overflow_message_(std::move(overflow_message)) {}

bool Outbox::push(Message message, std::size_t counted_frames) {
  bool stalled = false;
  {
    std::lock_guard lock(mutex_);
    if (finish_status_) return false;
    const std::size_t queued_frames = queued_frames_.load(std::memory_order_relaxed);
    if (max_frames_ > 0 && queued_frames + counted_frames > max_frames_) {
      drop_queue_locked();
      finish_status_ = grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED, overflow_message_);
      stalled = writing_;
    } else {
      queue_.push_back({std::move(message), counted_frames, std::chrono::steady_clock::now()});
      queued_frames_.store(queued_frames + counted_frames, std::memory_order_relaxed);
      if (queued_) queued_->fetch_add(1, std::memory_order_relaxed);
    }
  }
  if (stalled) target_.on_stalled();
  pump();
  std::lock_guard lock(mutex_);
  return !finish_status_ || finish_status_->ok();
}

void Outbox::close(const grpc::Status& status) {
  {
    std::lock_guard lock(mutex_);
    if (finish_status_) return;
    finish_status_ = status;
  }
  pump();
}

void Outbox::abort(const grpc::Status& status) {
  {
    std::lock_guard lock(mutex_);
    drop_queue_locked();
    if (!finish_status_) finish_status_ = status;
  }
  pump();
}

void Outbox::on_write_done(bool ok) {
  {
    std::lock_guard lock(mutex_);
    writing_ = false;
    if (ok && latency_ && in_flight_) {
      latency_->observe_us(
          std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() - in_flight_pushed_)
              .count());
    }
    in_flight_.reset();
    if (!ok) {
      drop_queue_locked();
      if (!finish_status_) {
        finish_status_ = grpc::Status(grpc::StatusCode::CANCELLED, "the client went away");
      }
    }
  }
  pump();
}

void Outbox::measure(Histogram& latency, std::atomic<std::int64_t>& queued) {
  std::lock_guard lock(mutex_);
  latency_ = &latency;
  queued_ = &queued;
  queued_->fetch_add(static_cast<std::int64_t>(queue_.size()), std::memory_order_relaxed);
}

void Outbox::drop_queue_locked() {
  if (queued_) queued_->fetch_sub(static_cast<std::int64_t>(queue_.size()), std::memory_order_relaxed);
  queue_.clear();
  queued_frames_.store(0, std::memory_order_relaxed);
}

std::optional<grpc::Status> Outbox::final_status() const {
  std::lock_guard lock(mutex_);
  return finish_status_;
}

std::size_t Outbox::queued_frames() const { return queued_frames_.load(std::memory_order_relaxed); }

void Outbox::pump() {
  const OutgoingMessage* write = nullptr;
  std::optional<grpc::Status> finish;
  {
    std::lock_guard lock(mutex_);
    if (writing_ || finish_called_) return;
    if (!queue_.empty()) {
      in_flight_ = std::move(queue_.front().message);
      in_flight_pushed_ = queue_.front().pushed;
      queued_frames_.store(queued_frames_.load(std::memory_order_relaxed) - queue_.front().counted_frames,
                           std::memory_order_relaxed);
      queue_.pop_front();
      if (queued_) queued_->fetch_sub(1, std::memory_order_relaxed);
      writing_ = true;
      write = in_flight_.get();
    } else if (finish_status_) {
      finish_called_ = true;
      finish = finish_status_;
    }
  }
  if (write) {
    target_.start_write(*write);
  } else if (finish) {
    target_.finish(*finish);
  }
}

}  // namespace lipsync::server
