// Listen: audio in, as it is spoken or as a whole recording; frames back while the speaker is
// still speaking. Settings first, then audio pieces, then `end`; back come a header, frame
// batches and a summary, and with a session name its subscribers get the same messages.
//
// Two ways through, chosen by `settings.recording`:
//   - live (the default): each piece goes through the stream's AudioStreamReader (raw PCM or a
//     WAV file, mixed down to mono) into its LiveRecognizer (PocketSphinx decoding the open
//     utterance as it arrives, utterances cut at pauses, closures refined from the signal; in a
//     language other than English, a LiveSynthesisAligner warping it against espeak-ng), whose
//     final phonemes feed a LiveRenderer; after each piece the frames up to the audio decoded less
//     the settling margin leave, rendered over the final phonemes and the recogniser's guess
//     (docs/streaming.md, "Live audio"). The margin is the latency budget less kProcessingMarginUs.
//   - a recording: the pieces are gathered until `end`, aligned whole with the offline aligner
//     and rendered with the streaming renderer at the settings' lookahead, so that the frames are
//     exactly those of `lipsync render X.wav` (with `--text-file`: the transcript).
//
// More words of a live stream's transcript (ListenWords, from a TTS as it produces them) go to the
// lane in the same queue as the audio, so that the recogniser gets them after the audio received
// before them.
//
// Decoding costs a tenth to a third of the audio's duration, far too long for a reaction: every
// piece is handed to the stream's lane on the recognition workers (a strand: its jobs run in
// order, one at a time; lanes run in parallel), which owns the reader, the recogniser and the
// renderer. The reactions only check the messages, queue the audio and read on; while more than
// kReadPauseBytes of audio wait for the lane the stream reads no more, so HTTP/2 flow control holds
// back a client that sends faster than the server decodes ("as fast as the server takes it").
// Likewise while more than kReadPauseFrames frames wait in the Outbox for a client that reads them
// slower than it sends audio (producer_admission.hpp): the stream reads again once the lane has
// caught up and at most kReadResumeFrames wait, so such a client's frames do not pile up here.
// Everything after the header leaves from the lane, through the Outbox (one write in flight). The
// reactor deletes itself through the lane (retire), after the jobs queued before OnDone; a job of a
// stream that failed or was cancelled does nothing.
//
// The audio is kept for the session's viewers (/audio?session=NAME) under the server's audio
// budget, at most kMaxKeptAudioBytes of it: a recording's before its first frame, a live stream's
// once it ends.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <variant>
#include <vector>

#include "call_log.hpp"
#include "lipsync/error.hpp"
#include "lipsync/live_renderer.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/setting_ranges.hpp"
#include "lipsync/speech/aligner.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/dtw_aligner.hpp"
#include "lipsync/speech/live_recognizer.hpp"
#include "lipsync/speech/live_synthesis_aligner.hpp"
#include "lipsync/tsan_handoff.hpp"
#include "rpc/outbox.hpp"
#include "rpc/plan.hpp"
#include "rpc/producer_admission.hpp"
#include "rpc/service.hpp"
#include "rpc/wire.hpp"
#include "sessions/live_streams.hpp"

namespace lipsync::server {
namespace {

/// The latency budget's range and default, ms.
constexpr std::uint32_t kMinLatencyMs = 100;
constexpr std::uint32_t kMaxLatencyMs = 2000;
constexpr std::uint32_t kDefaultLatencyMs = 200;
/// The part of the budget kept for the piece itself (20 ms from a microphone), the frames the
/// decoder holds back for its features (about 30 ms), decoding, rendering and sending; the rest is
/// how much audio the recogniser hears after a frame's time before the frame leaves.
constexpr std::int64_t kProcessingMarginUs = 90'000;
/// Audio waiting for the lane above which the stream stops reading (about 4 s of 48 kHz stereo).
constexpr std::size_t kReadPauseBytes = 768 * 1024;
/// The most of a stream's audio its session keeps for /audio (about 17 minutes of 16 kHz mono):
/// a stream of hours keeps its first minutes, not hours of samples.
constexpr std::size_t kMaxKeptAudioBytes = 32 * 1024 * 1024;
/// The longest transcript in the settings, and the most words' bytes in one ListenWords.
constexpr std::size_t kMaxTranscriptBytes = 16 * 1024;
/// The most transcript words a stream may hold ahead of the speech.
constexpr std::size_t kMaxWordsAhead = 8192;
/// The most notes a summary carries; the rest are counted.
constexpr std::size_t kMaxNotes = 32;
/// The source name errors in the audio are reported under.
constexpr const char* kAudioSource = "audio";

class ListenReactor final : public HandoffReactor<grpc::ServerBidiReactor<v1::ListenRequest, v1::TrackMessage>>,
                            public OutboxTarget,
                            public AbortableStream {
 public:
  ListenReactor(LipSyncService& service, grpc::CallbackServerContext* context)
      : service_(service),
        context_(context),
        outbox_(*this),
        log_("Listen", *context, &service.metrics()),
        frames_counter_(service.metrics().frames_sent.with({"Listen"})),
        lane_(service.recognition_workers()),
        admission_(service, "Listen", nullptr) {
    if (auto status = admission_.admit(*context_, *this, outbox_, log_, caller_); !status.ok()) {
      outbox_.close(status);
      return;
    }
    StartRead(&request_);
  }

  ~ListenReactor() override {
    if (kept_reserved_bytes_ > 0) service_.audio_budget().release(kept_reserved_bytes_);
  }

  void OnReadDone(bool ok) override {
    const HandoffScope handoff = reaction();
    if (!ok) {
      if (phase_ != Phase::ended) {
        fail(invalid("the request stream ended before `end` after " + std::to_string(bytes_received_) +
                     " bytes of audio: the client closed its side, or sent a message that is not a ListenRequest"),
             "producer disconnected before the end of the audio");
      }
      return;  // after `end` the lane finishes the call
    }
    grpc::Status status;
    try {
      status = handle(request_);
    } catch (const std::exception& error) {
      status = grpc::Status(grpc::StatusCode::INTERNAL, error.what());
    }
    if (!status.ok()) {
      fail(status, "producer failed: " + status.error_message());
      return;
    }
    std::lock_guard lock(audio_mutex_);
    if (pending_bytes_ > kReadPauseBytes || outbox_.queued_frames() > kReadPauseFrames) {
      read_paused_ = true;  // the lane or a write's completion reads on once both have caught up
      return;
    }
    StartRead(&request_);
  }

  void OnWriteDone(bool ok) override {
    const HandoffScope handoff = reaction();
    outbox_.on_write_done(ok);
    std::lock_guard lock(audio_mutex_);
    resume_reading_if_caught_up();
  }

  void OnCancel() override {
    const HandoffScope handoff = reaction();
    cancelled_ = true;
    stopped_ = true;
    outbox_.abort(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled"));
    fail_session("producer disconnected: the stream was cancelled");
  }

  void OnDone() override {
    last_reaction();
    admission_.leave_live_streams(*this);
    const auto status = cancelled_ ? cancelled_status() : outbox_.final_status().value_or(grpc::Status::OK);
    log_.ended(status, {{"audio_bytes", bytes_received_.load()}, {"frames", frames_sent_.load()}});
    admission_.give_back();
    stopped_ = true;
    service_.call_ended();
    lane_.retire([this] { delete this; });  // after the jobs still queued
  }

  void start_write(const OutgoingMessage& message) override {
    if (message.message().has_frames()) {
      frames_counter_.add(static_cast<std::uint64_t>(message.message().frames().t_us_size()));
    }
    StartWrite(&message.message());
  }
  void finish(const grpc::Status& status) override { Finish(status); }

  void abort_stream(const grpc::Status& status) override {
    stopped_ = true;
    outbox_.abort(status);
    fail_session("the server shut down: " + status.error_message());
  }

 private:
  enum class Phase { awaiting_settings, streaming, ended };

  grpc::Status handle(const v1::ListenRequest& request) {
    switch (phase_) {
      case Phase::awaiting_settings:
        if (!request.has_settings()) return invalid("first message must be settings");
        return start(request.settings());
      case Phase::streaming:
        if (request.has_audio()) return queue_audio(request.audio().data());
        if (request.has_words()) return queue_words(request.words());
        if (request.has_end()) {
          phase_ = Phase::ended;
          lane_.post([this] { on_lane([this] { return finish_audio(); }); });
          return grpc::Status();
        }
        if (request.has_settings()) return invalid("settings sent twice: only the first message may be settings");
        return invalid("empty ListenRequest after " + std::to_string(bytes_received_) + " bytes of audio");
      case Phase::ended:
        if (request.has_audio()) {
          return invalid("audio: " + std::to_string(request.audio().data().size()) +
                         " bytes received after `end` (the stream had " + std::to_string(bytes_received_) +
                         " bytes of audio)");
        }
        return invalid("message received after `end`");
    }
    return grpc::Status();
  }

  /// Checks the settings (on the reaction: quick), opens the session, sends the header and
  /// queues the recogniser's start on the lane.
  grpc::Status start(const v1::ListenSettings& settings) {
    const v1::AnimationSettings& animation = settings.animation();
    log_.set_session(animation.session());
    log_.started_line();
    if (wants_mesh(animation)) {
      return invalid("settings.animation.outputs.mesh: not offered by Listen yet (Render the phonemes with the mesh)");
    }
    // An English voice (or none) is heard by PocketSphinx in ARPAbet; any other espeak-ng voice by the
    // warp against espeak-ng's rendering of the transcript, in IPA.
    const std::string& voice = settings.voice();
    std::string heard_phone_set = "arpabet";
    if (!voice.empty()) {
      if (auto unknown = speech::unknown_voice_error(voice)) return invalid("settings.voice: " + *unknown);
      if (std::string set = speech::phone_set_for_voice(voice); set != "espeak") {
        synthesis_voice_ = voice;
        heard_phone_set = std::move(set);
      }
    }
    if (!animation.phone_set().empty() && animation.phone_set() != heard_phone_set) {
      return invalid("settings.animation.phone_set: '" + animation.phone_set() + "' given, but Listen animates the " +
                     (synthesis_voice_ ? "IPA phonemes of voice '" + voice + "'" : "recogniser's ARPAbet phonemes") +
                     " (leave it empty or '" + heard_phone_set + "')");
    }
    if (synthesis_voice_ && !settings.has_transcript()) {
      return invalid("settings.voice: '" + voice +
                     "' is not English, and without settings.transcript Listen hears English only (PocketSphinx's "
                     "phone loop): send the transcript (\"\" when its words come in ListenWords), or leave the voice "
                     "empty to hear the audio as English phones");
    }
    if (settings.has_transcript() && settings.transcript().size() > kMaxTranscriptBytes) {
      return invalid("settings.transcript: " + std::to_string(settings.transcript().size()) +
                     " bytes, longer than the limit of " + std::to_string(kMaxTranscriptBytes));
    }
    if (settings.has_latency_ms() && (settings.latency_ms() < kMinLatencyMs || settings.latency_ms() > kMaxLatencyMs)) {
      return invalid(out_of_range_text("settings.latency_ms", std::to_string(settings.latency_ms()),
                                       std::to_string(kMinLatencyMs) + " to " + std::to_string(kMaxLatencyMs) +
                                           ", default " + std::to_string(kDefaultLatencyMs)));
    }
    if (settings.recording() && settings.has_latency_ms()) {
      return invalid("settings.latency_ms: a recording's frames come after its last piece; leave it unset");
    }
    speech::AudioStreamReader::Encoding encoding = speech::AudioStreamReader::Encoding::pcm_s16le;
    switch (settings.encoding()) {
      case v1::AUDIO_ENCODING_UNSPECIFIED:
      case v1::AUDIO_ENCODING_PCM_S16LE:
        break;
      case v1::AUDIO_ENCODING_WAV:
        encoding = speech::AudioStreamReader::Encoding::wav;
        break;
      default:
        return invalid("settings.encoding: " + std::to_string(settings.encoding()) +
                       " is not an encoding Listen reads (PCM_S16LE or WAV)");
    }
    const std::uint32_t rate = settings.sample_rate_hz();
    const std::uint32_t channels = settings.channels();
    if (encoding == speech::AudioStreamReader::Encoding::pcm_s16le) {
      if (rate == 0) return invalid("settings.sample_rate_hz: required for PCM_S16LE audio (8000 to 48000)");
      if (channels > 2) {
        return invalid(out_of_range_text("settings.channels", std::to_string(channels), "1 or 2; 0 = 1"));
      }
    }
    if (rate != 0 && (rate < 8000 || rate > 48000)) {
      return invalid(out_of_range_text("settings.sample_rate_hz", std::to_string(rate), "8000 to 48000"));
    }
    if (auto status = service_.routing().check_metadata(*context_, animation.session()); !status.ok()) return status;
    if (auto status = resolve_settings(animation, service_.catalog(), true, plan_); !status.ok()) return status;
    if (synthesis_voice_) {
      plan_.phone_set = plan_.model->find_phone_set(heard_phone_set);
      if (plan_.phone_set == nullptr) {
        return invalid("settings.voice: '" + voice + "' is heard in the phone set '" + heard_phone_set +
                       "', which model '" + plan_.model->name + "' lacks");
      }
    }
    recording_ = settings.recording();
    if (settings.has_transcript()) transcript_ = settings.transcript();
    const std::uint32_t latency_ms = settings.has_latency_ms() ? settings.latency_ms() : kDefaultLatencyMs;
    settle_us_ = std::int64_t{latency_ms} * 1000 - kProcessingMarginUs;
    plan_.header.set_release_delay_us(recording_ ? 0 : std::int64_t{latency_ms} * 1000);

    v1::TrackMessage header_message;
    *header_message.mutable_header() = plan_.header;
    const Message header = make_message(std::move(header_message));
    if (!animation.session().empty()) {
      if (auto status = caller_.hold(Quota::sessions, session_hold_); !status.ok()) return status;
      std::shared_ptr<Session> session;
      if (auto status =
              service_.sessions().open(animation.session(), header, session, caller_.session_key(animation.session()));
          !status.ok()) {
        return status;
      }
      std::lock_guard lock(session_mutex_);
      session_ = std::move(session);
    }
    reader_.emplace(encoding, static_cast<int>(rate), static_cast<int>(channels == 0 && rate != 0 ? 1 : channels),
                    kAudioSource);
    outbox_.push(header);
    phase_ = Phase::streaming;
    if (!recording_) lane_.post([this] { on_lane([this] { return start_recognizer(); }); });
    return grpc::Status();
  }

  /// On the reaction: queues a piece for the lane.
  grpc::Status queue_audio(const std::string& data) {
    bytes_received_ += data.size();
    std::lock_guard lock(audio_mutex_);
    if (pending_.empty() || !std::holds_alternative<std::string>(pending_.back())) pending_.emplace_back(std::string());
    std::get<std::string>(pending_.back()) += data;
    pending_bytes_ += data.size();
    post_pending();
    return grpc::Status();
  }

  /// Posts a job that takes what is pending, unless one is queued already (it will take it too).
  void post_pending() {
    if (!job_posted_) {
      job_posted_ = true;
      lane_.post([this] { on_lane([this] { return decode_pending(); }); });
    }
  }

  /// On the reaction: checks more words of the transcript and queues them for the lane, after the
  /// audio received before them.
  grpc::Status queue_words(const v1::ListenWords& words) {
    if (recording_) {
      return invalid("words: a recording is aligned whole with settings.transcript; send its words there");
    }
    if (!transcript_) {
      return invalid(
          "words: the settings have no transcript, so the stream is recognised from the audio alone; set "
          "settings.transcript (to \"\" when every word comes in ListenWords)");
    }
    if (!words.text().empty() && words.timed_size() > 0) {
      return invalid("words: both text and timed words in one message; send one or the other");
    }
    std::size_t bytes = words.text().size();
    for (const v1::TimedWord& word : words.timed()) bytes += word.text().size();
    if (bytes > kMaxTranscriptBytes) {
      return invalid("words: " + std::to_string(bytes) + " bytes of words in one message, more than the limit of " +
                     std::to_string(kMaxTranscriptBytes));
    }
    std::lock_guard lock(audio_mutex_);
    pending_.emplace_back(words);
    post_pending();
    return grpc::Status();
  }

  /// On the lane: words into the recogniser, or kept for it until the audio's rate makes it.
  grpc::Status add_words(const v1::ListenWords& words) {
    if (!recognizer_) {
      early_words_.push_back(words);
      return grpc::Status();
    }
    try {
      if (words.timed_size() > 0) {
        std::vector<TimedWord> timed;
        timed.reserve(static_cast<std::size_t>(words.timed_size()));
        for (const v1::TimedWord& word : words.timed()) timed.push_back({word.text(), word.start_us()});
        recognizer_->add_timed_words(timed);
      } else {
        recognizer_->add_words(words.text());
      }
    } catch (const InputError& error) {
      return invalid("words: " + error.message());
    }
    if (recognizer_->words_ahead() > kMaxWordsAhead) {
      return {grpc::StatusCode::RESOURCE_EXHAUSTED,
              "words: " + std::to_string(recognizer_->words_ahead()) + " words ahead of the speech, more than " +
                  std::to_string(kMaxWordsAhead) + " (send the transcript as the speech goes)"};
    }
    return grpc::Status();
  }

  /// Runs `step` on the lane unless the stream has stopped; a failure ends the call and the session.
  template <class Step>
  void on_lane(Step step) {
    if (stopped_) return;
    grpc::Status status;
    try {
      status = step();
    } catch (const InputError& error) {
      status = invalid(error.what());
    } catch (const std::exception& error) {
      status = grpc::Status(grpc::StatusCode::INTERNAL, error.what());
    }
    if (!status.ok()) fail(status, "producer failed: " + status.error_message());
  }

  /// On the lane, first: the renderer, and the recogniser once the audio's rate is known (raw
  /// PCM's from the settings; a WAV's from its header, with its first samples).
  grpc::Status start_recognizer() {
    recognizer_options_.transcript = transcript_;
    recognizer_options_.commit_us = std::max(recognizer_options_.commit_us, settle_us_ + 100'000);
    live_.emplace(plan_.model->tables, *plan_.model->model, *plan_.phone_set, "recogniser", plan_.engine.segments,
                  plan_.engine.render);
    track_.channel_count = plan_.model->model->channel_count();
    track_.fps = plan_.engine.render.fps;
    if (reader_->sample_rate_hz() != 0) return make_recognizer(reader_->sample_rate_hz());
    return grpc::Status();
  }

  /// The recogniser for audio at `rate_hz`: for English, PocketSphinx with a decoder loaded ahead
  /// when one is ready (else it loads its own: about half a second), a transcript word the
  /// dictionary lacks being an InputError naming `settings.transcript`; for another voice, the warp
  /// against espeak-ng's rendering of the transcript (spoken now: a transcript espeak-ng cannot
  /// speak is an InputError naming it).
  grpc::Status make_recognizer(int rate_hz) {
    if (synthesis_voice_) {
      speech::LiveSynthesisOptions options;
      options.transcript = transcript_.value_or("");
      options.synthesis.voice = *synthesis_voice_;
      options.sample_rate_hz = rate_hz;
      options.commit_us = recognizer_options_.commit_us;
      recognizer_ = std::make_unique<speech::LiveSynthesisAligner>(options, "settings.transcript");
    } else {
      recognizer_options_.sample_rate_hz = rate_hz;
      speech::PreparedLiveDecoder decoder = service_.live_decoders().take(recognizer_options_);
      service_.metrics().listen_decoders.with({decoder ? "ahead" : "by_stream"}).add();
      recognizer_ = std::make_unique<speech::LiveRecognizer>(
          recognizer_options_, transcript_ ? "settings.transcript" : "settings", std::move(decoder));
    }
    for (const v1::ListenWords& words : early_words_) {
      if (auto status = add_words(words); !status.ok()) return status;
    }
    early_words_.clear();
    return grpc::Status();
  }

  /// On the lane: the audio and words queued so far, in the order they came; reading resumes if
  /// it waited for the lane.
  grpc::Status decode_pending() {
    std::deque<std::variant<std::string, v1::ListenWords>> taken;
    {
      std::lock_guard lock(audio_mutex_);
      taken.swap(pending_);
      pending_bytes_ = 0;
      job_posted_ = false;
      resume_reading_if_caught_up();
    }
    for (auto& item : taken) {
      grpc::Status status = std::holds_alternative<std::string>(item) ? decode(std::get<std::string>(item))
                                                                      : add_words(std::get<v1::ListenWords>(item));
      if (!status.ok()) return status;
    }
    return grpc::Status();
  }

  /// Under audio_mutex_: reads on if reading waits and neither the lane (audio) nor the client
  /// (frames) is behind any more; not once the stream is stopping or finishing.
  void resume_reading_if_caught_up() {
    if (!read_paused_ || stopped_ || pending_bytes_ > kReadPauseBytes || outbox_.queued_frames() > kReadResumeFrames ||
        outbox_.final_status().has_value()) {
      return;
    }
    read_paused_ = false;
    StartRead(&request_);
  }

  /// On the lane: `bytes` of audio decoded (live) or gathered (a recording).
  grpc::Status decode(const std::string& bytes) {
    samples_.clear();
    reader_->push(bytes, samples_);
    if (samples_.empty()) return grpc::Status();
    const int rate = reader_->sample_rate_hz();
    samples_read_ += samples_.size();
    const std::int64_t heard_ms = static_cast<std::int64_t>(samples_read_ * 1000 / static_cast<std::uint64_t>(rate));
    if (heard_ms > service_.config().max_listen_ms) {
      return {grpc::StatusCode::RESOURCE_EXHAUSTED,
              "audio: the stream reaches " + std::to_string(heard_ms) +
                  " ms, longer than --max-listen-ms=" + std::to_string(service_.config().max_listen_ms)};
    }
    keep_audio(rate);
    if (recording_) {
      if (heard_ms > static_cast<std::int64_t>(speech::AlignmentOptions{}.max_duration_s * 1000)) {
        return {grpc::StatusCode::RESOURCE_EXHAUSTED,
                "audio: the recording reaches " + std::to_string(heard_ms) + " ms, longer than the " +
                    std::to_string(static_cast<int>(speech::AlignmentOptions{}.max_duration_s)) +
                    " s a recording is aligned whole (send it live instead: recording false)"};
      }
      recording_audio_.sample_rate_hz = rate;
      recording_audio_.samples.insert(recording_audio_.samples.end(), samples_.begin(), samples_.end());
      return grpc::Status();
    }
    if (!recognizer_) {
      if (auto status = make_recognizer(rate); !status.ok()) return status;
    }
    recognizer_->push(samples_);
    render_live(false);
    return grpc::Status();
  }

  /// On the lane: the final phonemes into the renderer, then the frames due.
  void render_live(bool ended) {
    for (const LabeledInterval& phoneme : recognizer_->take_final()) live_->push_final(phoneme, track_);
    if (ended) {
      live_->finish(track_);
    } else {
      const std::vector<LabeledInterval> guess = recognizer_->guess();
      live_->emit_until(recognizer_->heard_us() - settle_us_, guess, track_);
    }
    for (std::string& note : recognizer_->take_notes()) keep_note(std::move(note));
    publish(recognizer_->heard_us());
  }

  /// On the lane, after `end`: the rest of the frames, the summary, OK.
  grpc::Status finish_audio() {
    grpc::Status status = decode_pending();
    if (!status.ok()) return status;
    reader_->finish();
    std::size_t phonemes = 0;
    std::int64_t duration_us = 0;
    if (recording_) {
      if (auto kept = kept_audio(); kept) set_session_audio(std::move(kept));
      if (auto rendered = render_recording(phonemes, duration_us); !rendered.ok()) return rendered;
    } else {
      if (samples_read_ == 0)
        return invalid("audio: the stream ended without audio (send ListenAudio pieces before `end`)");
      recognizer_->finish();
      render_live(true);
      phonemes = live_->final_count();
      duration_us = live_->final_end_us();
      if (auto kept = kept_audio(); kept) set_session_audio(std::move(kept));
    }
    v1::TrackMessage summary_message;
    encode_summary(frames_sent_, phonemes, duration_us, *summary_message.mutable_summary());
    for (const std::string& note : notes_) summary_message.mutable_summary()->add_notes(note);
    if (notes_dropped_ > 0) {
      summary_message.mutable_summary()->add_notes("and " + std::to_string(notes_dropped_) +
                                                   " more notes (the server's log has them all)");
    }
    const Message summary = make_message(std::move(summary_message));
    if (auto session = current_session()) session->finish(summary);
    outbox_.push(summary);
    outbox_.close(grpc::Status::OK);
    return grpc::Status();
  }

  /// A recording, aligned whole and rendered as `lipsync render X.wav` renders it.
  grpc::Status render_recording(std::size_t& phonemes, std::int64_t& duration_us) {
    if (recording_audio_.samples.empty()) {
      return invalid("audio: the recording has no samples (send ListenAudio pieces before `end`)");
    }
    speech::Alignment alignment;
    if (synthesis_voice_) {  // as `lipsync render X.wav --voice V --text-file T` aligns it
      speech::DtwAlignmentOptions options;
      options.transcript = transcript_.value_or("");
      options.synthesis.voice = *synthesis_voice_;
      alignment = speech::align_speech_to_synthesis(recording_audio_, kAudioSource, options);
    } else {
      speech::AlignmentOptions options;
      options.transcript = transcript_;
      alignment = speech::align_speech(recording_audio_, kAudioSource, options);
    }
    for (const std::string& note : alignment.notes) keep_note(note);
    LabeledUtterance utterance = alignment.phones;
    speech::cover_audio(utterance, recording_audio_.duration_us(), plan_.engine.render.fps);
    SegmentBuilder builder(*plan_.model->model, *plan_.phone_set, kAudioSource, plan_.engine.segments);
    StreamingRenderer renderer(plan_.model->tables, plan_.engine.render);
    track_.channel_count = plan_.model->model->channel_count();
    track_.fps = plan_.engine.render.fps;
    std::vector<Segment> segments;
    for (const LabeledInterval& phoneme : utterance.intervals) {
      segments.clear();
      builder.push(phoneme, segments);
      for (const Segment& segment : segments) renderer.push(segment, track_);
    }
    renderer.finish(track_);
    phonemes = utterance.intervals.size();
    duration_us = builder.end_us();
    publish(duration_us);
    return grpc::Status();
  }

  /// On the lane: sends the frames in track_ (and clears it), `heard_us` being how far the
  /// audio decoded reached when they left.
  void publish(std::int64_t heard_us) {
    for (std::size_t begin = 0; begin < track_.frame_count(); begin += kMaxFramesPerBatch) {
      const std::size_t end = std::min(track_.frame_count(), begin + kMaxFramesPerBatch);
      v1::TrackMessage batch;
      encode_frames(plan_, track_, begin, end, frames_sent_, *batch.mutable_frames(), encoder_);
      batch.mutable_frames()->set_release_lag_us(heard_us - track_.t_us[begin]);
      const Message message = make_message(std::move(batch));
      frames_sent_ += end - begin;
      if (auto session = current_session()) session->publish(message, end - begin);
      outbox_.push(message, end - begin);
    }
    track_.clear();
  }

  /// On the lane: a note for the log now and for the summary at the end (the first kMaxNotes).
  void keep_note(std::string note) {
    log_.line(spdlog::level::info, "listen note", note);
    if (notes_.size() < kMaxNotes) {
      notes_.push_back(std::move(note));
    } else {
      ++notes_dropped_;
    }
  }

  /// On the lane: keeps this piece's samples for the session's viewers while the budget allows.
  void keep_audio(int rate) {
    if (!keeping_audio_ || kept_full_ || !current_session()) return;
    const std::size_t bytes = samples_.size() * 2 + (kept_samples_.empty() ? 44 : 0);
    if (kept_reserved_bytes_ + bytes > kMaxKeptAudioBytes) {
      kept_full_ = true;  // the session keeps the audio so far
      log_.line(spdlog::level::info, "audio kept in part",
                "the session keeps the first " + std::to_string(kept_samples_.size() * 1000 / std::size_t(rate)) +
                    " ms of the stream's audio (" + std::to_string(kMaxKeptAudioBytes) + " bytes)");
      return;
    }
    if (!service_.audio_budget().try_reserve(bytes)) {
      log_.line(spdlog::level::warn, "audio not kept",
                "the session's sound would be over --max-session-audio-bytes " +
                    std::to_string(service_.audio_budget().limit_bytes()));
      service_.audio_budget().release(kept_reserved_bytes_);
      kept_reserved_bytes_ = 0;
      kept_samples_ = {};
      keeping_audio_ = false;
      return;
    }
    kept_reserved_bytes_ += bytes;
    kept_rate_hz_ = rate;
    kept_samples_.insert(kept_samples_.end(), samples_.begin(), samples_.end());
  }

  /// The kept audio as a WAV file under the budget (null when none was kept).
  std::shared_ptr<const std::string> kept_audio() {
    if (!keeping_audio_ || kept_samples_.empty()) return nullptr;
    speech::PcmAudio audio;
    audio.sample_rate_hz = kept_rate_hz_;
    audio.samples = std::move(kept_samples_);
    std::ostringstream wav;
    speech::write_wav(wav, audio);
    kept_reserved_bytes_ = 0;  // the kept string gives them back
    keeping_audio_ = false;
    return service_.audio_budget().keep(std::move(wav).str());
  }

  void set_session_audio(std::shared_ptr<const std::string> wav) {
    if (auto session = current_session()) session->set_audio_wav(std::move(wav));
  }

  void fail(const grpc::Status& status, const std::string& reason) {
    stopped_ = true;
    outbox_.close(status);
    fail_session(reason);
  }

  void fail_session(const std::string& reason) {
    if (auto session = current_session()) session->fail(reason);
  }

  std::shared_ptr<Session> current_session() {
    std::lock_guard lock(session_mutex_);
    return session_;
  }

 private:
  LipSyncService& service_;
  grpc::CallbackServerContext* context_;
  Caller caller_;  // the tenant; its quotas are held until the reactor is deleted
  QuotaHold session_hold_;
  Outbox outbox_;
  CallLog log_;
  Counter& frames_counter_;
  FaceLane lane_;                // on the recognition workers: everything after the header runs here
  ProducerAdmission admission_;  // the stream quota's unit is held until the reactor is deleted
  std::atomic<bool> cancelled_ = false;
  std::atomic<bool> stopped_ = false;  // failed, cancelled or done: queued lane jobs do nothing
  Phase phase_ = Phase::awaiting_settings;
  v1::ListenRequest request_;
  std::atomic<std::uint64_t> bytes_received_ = 0;

  // Set by start() on the reaction before the lane's first job, then the lane's.
  Plan plan_;
  bool recording_ = false;
  std::optional<std::string> transcript_;
  std::int64_t settle_us_ = 0;
  std::optional<speech::AudioStreamReader> reader_;

  // Between the reactions and the lane.
  std::mutex audio_mutex_;
  // Audio (its bytes) and words received and not yet taken by the lane, in the order they came.
  std::deque<std::variant<std::string, v1::ListenWords>> pending_;
  std::size_t pending_bytes_ = 0;  // of audio in pending_
  bool job_posted_ = false;        // a job is queued that will take pending_
  bool read_paused_ = false;

  // The lane's.
  speech::LiveRecognitionOptions recognizer_options_;
  std::optional<std::string> synthesis_voice_;  // a voice other than English: heard by the warp
  std::unique_ptr<speech::LivePhoneSource> recognizer_;
  std::optional<LiveRenderer> live_;
  std::vector<v1::ListenWords> early_words_;  // words that came before the recogniser
  std::vector<std::string> notes_;
  std::size_t notes_dropped_ = 0;
  speech::PcmAudio recording_audio_;
  std::vector<std::int16_t> samples_;  // this piece's, mono
  std::uint64_t samples_read_ = 0;
  Track track_;
  StreamEncoder encoder_;
  std::atomic<std::uint64_t> frames_sent_ = 0;
  bool keeping_audio_ = true;
  bool kept_full_ = false;  // kMaxKeptAudioBytes reached: nothing more is kept
  std::vector<std::int16_t> kept_samples_;
  int kept_rate_hz_ = 16000;
  std::size_t kept_reserved_bytes_ = 0;

  std::mutex session_mutex_;
  std::shared_ptr<Session> session_;
};

}  // namespace

grpc::ServerBidiReactor<v1::ListenRequest, v1::TrackMessage>* LipSyncService::Listen(
    grpc::CallbackServerContext* context) {
  handoff_acquire(this);  // the service as built before the server started (tsan_handoff.hpp)
  auto* reactor = new ListenReactor(*this, context);
  reactor->handed_off();
  return reactor;
}

}  // namespace lipsync::server
