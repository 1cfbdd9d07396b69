// Frames on a deadline: the renderer of a live stream, whose frames must leave before the
// phonemes they show are final.
//
// A live recogniser (lipsync/speech/live_recognizer.hpp) knows two kinds of phonemes: final ones,
// which never change, and a guess of the newest ones, which may. The streaming renderer
// (renderer.hpp) takes only final segments and releases a frame once its lookahead is known: on
// live speech that is a phoneme or more behind the voice. A live stream has a latency budget
// instead: the frame at time t leaves once the audio has reached t plus a settling margin,
// whatever is final by then.
//
// So this renderer keeps a StreamingRenderer fed with the final phonemes only (through a
// SegmentBuilder, as every other path builds segments), and at each deadline renders the frames
// that are due on a copy of it, fed with the guess after the final phonemes and then finished:
// the final phonemes and the guess together are the best knowledge of the utterance so far,
// evaluated with the same scheduler and Eq. 4-5. A frame leaves once and is never taken back: the
// stream is the frames in time order, each as first computed, so the frames of a time that was
// guessed keep the guess even when the final phonemes later differ. Frames the exact renderer
// releases beyond every deadline so far (at the end of an utterance, once everything is final)
// leave as they are: where the deadline never ran ahead of the final phonemes (a whole recording
// sent faster than it is decoded, the end of the stream) the stream is the exact render.
//
// Cost per deadline: one copy of the streaming renderer's window (15 segments and the frames
// waiting for their lookahead), into a copy kept for the purpose, so that its vectors keep their
// room, and the evaluation of those frames, about a microsecond each. Pure computation.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/utterance.hpp"

namespace lipsync {

class LiveRenderer {
 public:
  /// `model` and `phone_set` must outlive the renderer; `source` names the stream in errors.
  LiveRenderer(std::shared_ptr<const CoarticulationTables> tables, const ArticulationModel& model,
               const PhoneSet& phone_set, std::string source, SegmentOptions segment_options,
               const RenderOptions& options);

  /// Adds the next final phoneme (contiguous with the previous one) and appends to `out` the frames
  /// after the last one emitted that the exact renderer released. Throws InputError for a phoneme
  /// the phone set does not know or bad timing (the renderer is then unchanged).
  void push_final(const LabeledInterval& phoneme, Track& out);
  /// Appends to `out` the frames after the last one emitted, up to and including `until_us`,
  /// rendered over the final phonemes followed by `guess` (contiguous with them). A guessed phoneme
  /// the phone set does not know ends the guess there (it is not an error: a guess may be wrong).
  void emit_until(std::int64_t until_us, std::span<const LabeledInterval> guess, Track& out);
  /// The phonemes have ended: appends every frame still due.
  void finish(Track& out);

  /// Time of the last frame emitted; -1 before the first.
  std::int64_t emitted_until_us() const { return emitted_until_us_; }
  /// End of the final phonemes so far.
  std::int64_t final_end_us() const { return builder_.end_us(); }
  /// Final phonemes pushed so far.
  std::size_t final_count() const { return final_count_; }

 private:
  /// Appends the frames of `from` after emitted_until_us_ (and at most `until_us`) to `out`.
  void take_frames(const Track& from, std::int64_t until_us, Track& out);

  SegmentBuilder builder_;
  StreamingRenderer renderer_;
  // The final state copied at each deadline and fed the guess.
  SegmentBuilder guess_builder_;
  StreamingRenderer guess_renderer_;
  std::vector<Segment> segments_;  // scratch
  Track released_;                 // scratch: what a renderer released
  std::int64_t emitted_until_us_ = -1;
  std::size_t final_count_ = 0;
};

}  // namespace lipsync
