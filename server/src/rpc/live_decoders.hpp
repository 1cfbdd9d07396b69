// Decoders for Listen's live streams, loaded ahead of the streams that take them.
//
// A LiveRecognizer's PocketSphinx decoder takes about half a second to load (the acoustic model, a
// 130,000-word dictionary and, without a transcript, the phone loop). A stream that loads its own
// spends that before its first frame: the first frames of a voice came 0.5-0.9 s late (the page's
// microphone, Godot's live mode). The pool keeps one spare decoder per kind (with or without a
// transcript, and the recogniser's tuning: speech::same_live_decoder): a stream takes it and its
// first frames leave within the budget, and the next spare is loaded on the recognition workers
// while the stream runs. A kind's first stream finds none and loads its own (the pool then starts
// keeping one, and one of the other kind: with a transcript or from the audio alone, the same
// tuning), so a server that never listens loads nothing and only a server's first live stream
// waits for its decoder; at most kMaxKinds kinds are kept, the one least recently asked for goes
// first. A spare is a whole decoder (about 30 MB). Spares load one at a time on a thread of the
// pool's own at a low priority (nice 10), so that a load (about 0.65 s of CPU) does not slow the
// live streams that have just started, whose recognisers run on the recognition workers.
#pragma once

#include <cstddef>
#include <memory>

#include "face/face_workers.hpp"

// lipsync/speech/live_recognizer.hpp, declared only: the service's header includes this one, and
// not every target that includes the service's header sees lipsync::speech's headers.
namespace lipsync::speech {
struct LiveRecognitionOptions;
class LiveDecoder;
struct LiveDecoderDeleter;
using PreparedLiveDecoder = std::unique_ptr<LiveDecoder, LiveDecoderDeleter>;
}  // namespace lipsync::speech

namespace lipsync::server {

class LiveDecoderPool {
 public:
  /// The most kinds of decoder kept ready at once.
  static constexpr std::size_t kMaxKinds = 4;

  LiveDecoderPool();
  LiveDecoderPool(const LiveDecoderPool&) = delete;
  LiveDecoderPool& operator=(const LiveDecoderPool&) = delete;

  /// A decoder loaded for recognisers with `options`, or null when none is ready (the stream loads
  /// its own); either way the next one of that kind is loaded.
  speech::PreparedLiveDecoder take(const speech::LiveRecognitionOptions& options);
  /// Decoders loaded and not yet taken (lipsyncd_listen_spare_decoders).
  std::size_t ready() const;

 private:
  struct Shelf;
  /// Loads a decoder of `options`' kind on loader_ and shelves it.
  void load(const speech::LiveRecognitionOptions& options);
  std::shared_ptr<Shelf> shelf_;                       // shared with the loads under way
  FaceWorkers loader_{1, FaceWorkers::Priority::low};  // last: it finishes a load under way first
};

}  // namespace lipsync::server
