// Speak: text in, voice and face out of one call, on one utterance clock.
//
// The reaction that starts the call only checks the request (text, voice,
// rate, settings, the session name) and opens the session; everything else
// runs on the speech thread (speech_thread.hpp), one call at a time, because
// espeak-ng is a process-wide, non-re-entrant synthesiser:
//   1. lipsync::speech::synthesize speaks the text and reports the phonemes it
//      spoke, timed on the audio's own samples (the espeak phone set), and notes on
//      its reading (words read in another language...), which the summary carries;
//      a reading that would be nonsense is refused (INVALID_ARGUMENT naming `text`);
//   2. lipsync::speech::cover_audio appends the silence that takes the track to
//      a frame at or after the audio's end, as `lipsync say` does;
//   3. the phonemes go one at a time through the same PhonemeInput and
//      StreamingRenderer as Animate's, and each released frame batch through the
//      same wire encoding and, with a session name, to the session as it is
//      produced, so subscribers follow a Speak exactly as they follow an Animate.
//      The session also keeps the audio as a WAV file (stored before the first
//      frames), which the browser viewer serves as /audio?session=NAME.
// The frames therefore equal an offline render of the header's phonemes bit for
// bit (lookahead 7, the default). The caller's messages, prepared meanwhile in
// utterance-time order (each audio chunk before the frames at or after its
// start), are then written back to back, as fast as the client reads: the
// whole utterance is bounded by the text limit, so nothing waits on a pace.
//
// Who owns the reactor: gRPC until OnDone, and the speech thread while the
// call's job is queued or running there. The one that lets go last deletes it.
// Finish is called once (`finished_`), and never while a write is in flight.
// At the drain deadline the call is aborted like Animate's and Subscribe's
// streams (live_streams.hpp): ABORTED at once if it waits for the speech
// thread, synthesises, or is between writes; after the write in flight
// otherwise. A job whose call has ended (aborted, or finished after OnDone)
// stops right after its synthesis and sends nothing.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "call_log.hpp"
#include "lipsync/error.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/synthesizer.hpp"
#include "lipsync/tsan_handoff.hpp"
#include "rpc/phoneme_input.hpp"
#include "rpc/plan.hpp"
#include "rpc/service.hpp"
#include "rpc/wire.hpp"
#include "sessions/live_streams.hpp"

namespace lipsync::server {
namespace {

/// The longest text a Speak call may carry (about four minutes of speech at 175 words per minute).
constexpr std::size_t kMaxTextBytes = 4096;
/// The longest voice name accepted (espeak-ng's are a few characters, "en-us", "de+f3").
constexpr std::size_t kMaxVoiceBytes = 64;
/// Audio per AudioChunk.
constexpr std::int64_t kAudioChunkUs = 100'000;

grpc::Status check_text(const std::string& text) {
  if (text.find_first_not_of(" \t\r\n") == std::string::npos) {
    return invalid("text: empty (Speak needs something to say)");
  }
  if (text.size() > kMaxTextBytes) {
    return invalid("text: " + std::to_string(text.size()) + " bytes, longer than the limit of " +
                   std::to_string(kMaxTextBytes) + " bytes");
  }
  return grpc::Status::OK;
}

/// The request's voice and rate as synthesis options, or INVALID_ARGUMENT naming the field.
grpc::Status synthesis_options(const v1::SpeakRequest& request, speech::SynthesisOptions& options) {
  if (request.voice().size() > kMaxVoiceBytes) {
    return invalid("voice: the name is longer than " + std::to_string(kMaxVoiceBytes) + " bytes");
  }
  if (!request.voice().empty()) options.voice = request.voice();
  if (const std::optional<std::string> unknown = speech::unknown_voice_error(options.voice)) {
    return invalid("voice: " + *unknown);  // names the closest voices
  }
  const std::uint32_t rate = request.words_per_minute();
  const IntSetting& setting = speech::kWordsPerMinuteSetting;
  if (rate != 0 && (rate < setting.min || rate > setting.max)) {
    return invalid(out_of_range_text("words_per_minute", std::to_string(rate),
                                     range_text(setting, false) + "; 0 = " + std::to_string(setting.default_value)));
  }
  if (rate != 0) options.words_per_minute = static_cast<int>(rate);
  return grpc::Status::OK;
}

/// Speak's settings: Animate's, with the phone set of the voice's phonemes (espeak for English
/// voices, ipa for the others) and without the mesh.
grpc::Status speak_settings(const v1::AnimationSettings& requested, const speech::SynthesisOptions& options,
                            v1::AnimationSettings& settings) {
  settings = requested;
  const std::string phone_set = speech::phone_set_for_voice(options.voice);
  if (settings.phone_set().empty()) settings.set_phone_set(phone_set);
  if (settings.phone_set() != phone_set) {
    return invalid("settings.phone_set: '" + settings.phone_set() +
                   "' given, but Speak animates espeak-ng's phonemes (leave it empty or '" + phone_set + "')");
  }
  if (wants_mesh(settings)) {
    return invalid(
        "settings.outputs.mesh: not offered by Speak (its solver would hold up the speech thread); "
        "Render the header's phonemes with the mesh output instead");
  }
  return grpc::Status::OK;
}

class SpeakReactor final : public HandoffReactor<grpc::ServerWriteReactor<v1::SpeakResponse>>, public AbortableStream {
 public:
  SpeakReactor(LipSyncService& service, grpc::CallbackServerContext* context, const v1::SpeakRequest& request)
      : service_(service), context_(context), request_(request), log_("Speak", *context, &service.metrics()) {
    grpc::Status status = service_.admission().admit_stream(context_->peer());
    if (!status.ok()) {
      finish(status);
      return;
    }
    admitted_ = true;
    service_.live_streams().add(*this);
    // The tenant (tenants.hpp): its key, its streams, its session and phoneme rate below.
    if (status = service_.tenants().authenticate(*context_, "Speak", caller_); status.ok()) {
      log_.set_tenant(caller_.tenant());
      status = caller_.hold(Quota::streams, stream_hold_);
    }
    if (!status.ok()) {
      finish(status);
      return;
    }
    run_step([this] { return start(); });
  }

  void OnWriteDone(bool ok) override {
    const HandoffScope handoff = reaction();
    {
      std::lock_guard lock(mutex_);
      writing_ = false;
    }
    if (!ok) {
      finish(grpc::Status(grpc::StatusCode::CANCELLED, "the client stopped reading"));
      return;
    }
    write_next();
  }

  void OnCancel() override {
    const HandoffScope handoff = reaction();
    cancelled_ = true;
  }

  void OnDone() override {
    last_reaction();
    if (admitted_) service_.live_streams().remove(*this);
    bool last_owner = false;
    grpc::Status status;
    {
      std::lock_guard lock(mutex_);
      status = final_status_;
      done_ = true;
      last_owner = !speech_thread_owns_;
    }
    // The counts are atomics: an aborted call's job may still be rendering.
    log_.ended(cancelled_ ? cancelled_status() : status,
               {{"samples", samples_sent_.load()}, {"frames", frames_sent_.load()}});
    if (admitted_) service_.admission().release_stream();
    service_.call_ended();
    if (last_owner) delete this;
  }

  /// At the drain deadline (live_streams.hpp): ends the call with `status` now, or,
  /// with a write in flight, when it completes; queued messages are not sent.
  void abort_stream(const grpc::Status& status) override {
    {
      std::lock_guard lock(mutex_);
      if (finished_) return;
      abort_status_ = status;
      if (writing_) return;  // OnWriteDone finishes with it
      finished_ = true;
      final_status_ = status;
    }
    Finish(status);
  }

 private:
  /// Checks the request, opens the session and queues the synthesis (on a reaction: quick).
  grpc::Status start() {
    if (auto status = check_text(request_.text()); !status.ok()) return status;
    if (auto status = synthesis_options(request_, options_); !status.ok()) return status;
    v1::AnimationSettings settings;
    if (auto status = speak_settings(request_.settings(), options_, settings); !status.ok()) return status;
    if (auto status = service_.routing().check_metadata(*context_, settings.session()); !status.ok()) return status;
    if (auto status = resolve_settings(settings, service_.catalog(), true, plan_); !status.ok()) return status;
    if (!settings.session().empty()) {
      v1::TrackMessage header_message;
      *header_message.mutable_header() = plan_.header;
      const Message header = make_message(std::move(header_message));
      if (auto status = caller_.hold(Quota::sessions, session_hold_); !status.ok()) return status;
      if (auto status =
              service_.sessions().open(settings.session(), header, session_, caller_.session_key(settings.session()));
          !status.ok()) {
        return status;
      }
      session_name_ = settings.session();
    }
    log_.set_session(session_name_);
    log_.started_line({{"text_bytes", static_cast<std::uint64_t>(request_.text().size())}});
    // The request is gRPC's and goes at OnDone, which may come before the job ends.
    text_ = request_.text();
    // From here on the speech thread shares the reactor (see the top of the file).
    std::lock_guard lock(mutex_);
    speech_thread_owns_ = true;
    grpc::Status posted = service_.speech_thread().post([this] { run(); });
    if (!posted.ok()) speech_thread_owns_ = false;
    return posted;
  }

  /// On the speech thread: synthesis, rendering, then the first write (or Finish).
  void run() {
    if (cancelled_) {
      fail_session("producer disconnected: the Speak call was cancelled");
      finish(grpc::Status(grpc::StatusCode::CANCELLED, "cancelled before synthesis"));
    } else if (ended()) {
      fail_session("producer failed: " + abort_status().error_message());  // aborted while it waited
    } else if (run_step([this] { return speak(); })) {
      write_next();
    }
    bool last_owner = false;
    {
      std::lock_guard lock(mutex_);
      speech_thread_owns_ = false;
      last_owner = done_;
    }
    if (last_owner) delete this;
  }

  /// Whether Finish was called (the call was aborted, or failed).
  bool ended() {
    std::lock_guard lock(mutex_);
    return finished_;
  }

  /// Runs `step`; a failure (INTERNAL if it throws: nothing may escape a reaction or the
  /// speech thread) fails the session and finishes the call. Returns whether it succeeded.
  template <class Step>
  bool run_step(Step step) {
    grpc::Status status;
    try {
      status = step();
    } catch (const std::exception& error) {
      status = grpc::Status(grpc::StatusCode::INTERNAL, error.what());
    }
    if (status.ok()) return true;
    fail_session("producer failed: " + status.error_message());
    finish(status);
    return false;
  }

  grpc::Status speak() {
    speech::Synthesis speech;
    try {
      speech = speech::synthesize(text_, options_);
    } catch (const InputError& error) {
      // synthesize refuses a voice espeak-ng does not know, or a text it finds nothing to say in.
      const bool voice = std::string(error.what()).find("unknown voice") != std::string::npos;
      return invalid((voice ? "voice: " : "text: ") + std::string(error.what()));
    }
    if (ended()) return abort_status();  // aborted while it spoke: nothing more to do
    if (auto status = caller_.take_phonemes(speech.phonemes.intervals.size()); !status.ok()) return status;
    audio_ = std::move(speech.audio);
    speech::cover_audio(speech.phonemes, audio_.duration_us(), plan_.engine.render.fps);
    if (session_) {  // the viewer plays it (GET /audio?session=NAME), before the first frames are published
      std::ostringstream wav;
      speech::write_wav(wav, audio_);
      std::string bytes = std::move(wav).str();
      if (service_.audio_budget().try_reserve(bytes.size())) {
        session_->set_audio_wav(service_.audio_budget().keep(std::move(bytes)));
      } else {  // the call goes on (the caller gets its sound in the responses); only /audio lacks it
        log_.line(spdlog::level::warn, "audio not kept",
                  std::to_string(bytes.size()) + " bytes would be over --max-session-audio-bytes " +
                      std::to_string(service_.audio_budget().limit_bytes()));
      }
    }

    v1::SpeakHeader& header = *responses_.emplace_back().mutable_header();
    header.set_sample_rate_hz(static_cast<std::uint32_t>(audio_.sample_rate_hz));
    header.set_channels(1);
    header.set_sample_format(v1::SAMPLE_FORMAT_PCM_S16LE);
    header.set_sample_count(audio_.samples.size());
    header.set_audio_duration_us(audio_.duration_us());
    *header.mutable_track() = plan_.header;
    header.set_voice(options_.voice);
    header.set_words_per_minute(static_cast<std::uint32_t>(options_.words_per_minute));
    for (const LabeledInterval& interval : speech.phonemes.intervals) {
      v1::Phoneme& phoneme = *header.add_phonemes();
      phoneme.set_label(interval.label);
      phoneme.set_start_us(interval.start_us);
      phoneme.set_end_us(interval.end_us);
    }

    PhonemeInput input(plan_, service_.config());
    StreamingRenderer renderer(plan_.model->tables, plan_.engine.render);
    Track track;
    track.channel_count = plan_.model->model->channel_count();
    track.fps = plan_.engine.render.fps;
    std::vector<Segment> segments;
    for (const v1::Phoneme& phoneme : header.phonemes()) {
      if (auto status = input.push(phoneme, segments); !status.ok()) return status;
      for (const Segment& segment : segments) renderer.push(segment, track);
      segments.clear();
      send_frames(track);
    }
    renderer.finish(track);
    send_frames(track);
    send_audio_until(audio_.samples.size());

    v1::SpeakSummary& speak_summary = *responses_.emplace_back().mutable_summary();
    encode_summary(frames_sent_, input.count(), input.end_us(), *speak_summary.mutable_track());
    // How espeak-ng read the text, when that needs saying (words read by another language's rules...).
    for (const std::string& note : speech.notes) speak_summary.mutable_track()->add_notes(note);
    if (session_) {
      v1::TrackMessage summary;
      *summary.mutable_summary() = speak_summary.track();
      session_->finish(make_message(std::move(summary)));
    }
    speak_summary.set_sample_count(samples_sent_);
    speak_summary.set_audio_duration_us(audio_.duration_us());
    return grpc::Status::OK;
  }

  /// Queues the frames the renderer released since the last call, after the
  /// audio chunks that start at or before the last of them; publishes them to the session.
  void send_frames(Track& track) {
    if (track.frame_count() == 0) return;
    send_audio_until(sample_at(track.t_us.back()) + 1);
    for (std::size_t begin = 0; begin < track.frame_count(); begin += kMaxFramesPerBatch) {
      const std::size_t end = std::min(track.frame_count(), begin + kMaxFramesPerBatch);
      v1::FrameBatch& batch = *responses_.emplace_back().mutable_frames();
      encode_frames(plan_, track, begin, end, frames_sent_, batch, encoder_);
      frames_sent_ += end - begin;
      if (session_) {
        v1::TrackMessage message;
        *message.mutable_frames() = batch;
        session_->publish(make_message(std::move(message)), end - begin);
      }
    }
    track.clear();
  }

  /// The first sample at or after utterance time `t_us`.
  std::size_t sample_at(std::int64_t t_us) const {
    const std::int64_t rate = audio_.sample_rate_hz;
    return static_cast<std::size_t>((t_us * rate + 999'999) / 1'000'000);
  }

  /// Queues whole audio chunks until every chunk starting before sample `limit` is queued.
  void send_audio_until(std::size_t limit) {
    const auto chunk_samples = static_cast<std::size_t>(audio_.sample_rate_hz * kAudioChunkUs / 1'000'000);
    const std::size_t total = audio_.samples.size();
    while (samples_sent_ < std::min(limit, total)) {
      const std::size_t count = std::min(chunk_samples, total - samples_sent_);
      v1::AudioChunk& chunk = *responses_.emplace_back().mutable_audio();
      chunk.set_first_sample(samples_sent_);
      chunk.set_start_us(static_cast<std::int64_t>(samples_sent_) * 1'000'000 / audio_.sample_rate_hz);
      std::string& pcm = *chunk.mutable_pcm();
      pcm.reserve(count * 2);
      for (std::size_t i = samples_sent_; i < samples_sent_ + count; ++i) {
        const auto sample = static_cast<std::uint16_t>(audio_.samples[i]);
        pcm.push_back(static_cast<char>(sample & 0xFF));
        pcm.push_back(static_cast<char>(sample >> 8));
      }
      samples_sent_ += count;
    }
  }

  /// Writes the next prepared message, or finishes: with OK after the last, or with
  /// the drain's status once the call was aborted.
  void write_next() {
    const v1::SpeakResponse* message = nullptr;
    grpc::Status end = grpc::Status::OK;
    {
      std::lock_guard lock(mutex_);
      if (finished_) return;
      if (abort_status_) {
        end = *abort_status_;
      } else if (next_ < responses_.size()) {
        message = &responses_[next_++];
        writing_ = true;
      }
    }
    if (message) {
      StartWrite(message);
    } else {
      finish(end);
    }
  }

  /// Finishes the call with `status` unless it was finished already.
  void finish(const grpc::Status& status) {
    {
      std::lock_guard lock(mutex_);
      if (finished_) return;
      finished_ = true;
      final_status_ = status;
    }
    Finish(status);
  }

  grpc::Status abort_status() {
    std::lock_guard lock(mutex_);
    return abort_status_.value_or(final_status_);
  }

  void fail_session(const std::string& reason) {
    if (session_) session_->fail(reason);
  }

  LipSyncService& service_;
  grpc::CallbackServerContext* context_;
  const v1::SpeakRequest& request_;
  CallLog log_;
  bool admitted_ = false;
  Caller caller_;  // the tenant; its quotas are held until the reactor is deleted
  QuotaHold stream_hold_, session_hold_;
  std::atomic<bool> cancelled_ = false;
  // Who may still touch the reactor, and where the call stands (see the top of the file).
  std::mutex mutex_;
  bool speech_thread_owns_ = false;
  bool done_ = false;      // OnDone has run
  bool finished_ = false;  // Finish was called
  bool writing_ = false;   // a StartWrite has not completed
  std::optional<grpc::Status> abort_status_;
  std::string text_;
  speech::SynthesisOptions options_;
  Plan plan_;
  std::shared_ptr<Session> session_;
  std::string session_name_;
  // Filled on the speech thread, then written in order by the reactions; a
  // deque, so that the messages stay where StartWrite was given them.
  speech::PcmAudio audio_;
  std::deque<v1::SpeakResponse> responses_;
  std::size_t next_ = 0;
  StreamEncoder encoder_;
  std::atomic<std::uint64_t> frames_sent_ = 0;
  std::atomic<std::uint64_t> samples_sent_ = 0;
  grpc::Status final_status_;
};

}  // namespace

grpc::ServerWriteReactor<v1::SpeakResponse>* LipSyncService::Speak(grpc::CallbackServerContext* context,
                                                                   const v1::SpeakRequest* request) {
  handoff_acquire(this);  // the service as built before the server started (tsan_handoff.hpp)
  auto* reactor = new SpeakReactor(*this, context, *request);
  reactor->handed_off();
  return reactor;
}

}  // namespace lipsync::server
