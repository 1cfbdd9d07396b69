// `lipsync loadtest --listen`: N live voices at once, each a Listen stream of speech sent at the
// pace it is spoken, for --duration seconds; then a report: the latency a user sees, the frames
// that came back, errors by status code, and whether every stream came back whole.
//
// The speech is kSentences spoken once by espeak-ng (in this process) and resampled to 16 kHz, a
// microphone's rate. Stream s speaks them in turn from sentence s on, each followed by kPauseUs of
// silence (so the server cuts an utterance at every sentence, as a speaker's pauses make it), in
// kPieceUs pieces, piece k leaving k × kPieceUs after the stream's start; the streams start
// spread over the first second so that their pieces do not all leave together. One thread sends
// every stream's pieces; the frames come back on gRPC's threads. With --transcript each stream's
// settings hold an empty transcript and each sentence's words go as ListenWords just before its
// first piece, as a TTS that knows its text before its audio would send them.
//
// A frame's latency is measured as `lipsync listen` measures it: from the sending of the piece
// that holds the frame's time to the frame's arrival. A stream is whole when it ended OK, its
// frames came in time order, the summary counts the frames received, and they reach to within a
// frame period of the audio's end.
#include "listen_load.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "cli_error.hpp"
#include "lipsync/client/animation_client.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/synthesizer.hpp"
#include "loadtest_shared.hpp"
#include "network.hpp"

namespace lipsync::cli {
namespace {

using Clock = std::chrono::steady_clock;

constexpr int kRateHz = 16000;
constexpr std::int64_t kPieceUs = 20'000;
constexpr std::size_t kPieceSamples = kRateHz * kPieceUs / 1'000'000;
constexpr std::int64_t kPauseUs = 600'000;
constexpr auto kGrace = std::chrono::seconds(30);
constexpr std::array<const char*, 8> kSentences = {
    "The birch canoe slid on the smooth planks.",  "Glue the sheet to the dark blue background.",
    "It's easy to tell the depth of a well.",      "These days a chicken leg is a rare dish.",
    "Rice is often served in round bowls.",        "The juice of lemons makes fine punch.",
    "The box was thrown beside the parked truck.", "The hogs were fed chopped corn and garbage.",
};

/// A sentence's audio at kRateHz followed by its pause, and its words.
struct Sentence {
  std::vector<std::int16_t> samples;
  std::string text;
};

std::vector<Sentence> speak_sentences() {
  std::vector<Sentence> sentences;
  for (const char* text : kSentences) {
    const speech::PcmAudio audio = speech::resample(speech::synthesize(text).audio, kRateHz);
    Sentence sentence{audio.samples, text};
    sentence.samples.insert(sentence.samples.end(), static_cast<std::size_t>(kRateHz * kPauseUs / 1'000'000), 0);
    sentences.push_back(std::move(sentence));
  }
  return sentences;
}

/// One live voice: its place in the speech, when each piece left, what came back.
class Voice {
 public:
  Voice(std::size_t first_sentence, std::size_t pieces, Clock::time_point start)
      : sentence_(first_sentence), sent_ns_(pieces), start_(start) {}

  /// The next piece of the voice's speech, and the words of a sentence that starts in it.
  std::string next_piece(const std::vector<Sentence>& sentences, std::string& words) {
    std::vector<std::int16_t> piece;
    while (piece.size() < kPieceSamples) {
      const Sentence& sentence = sentences[sentence_ % sentences.size()];
      if (offset_ == 0) words += (words.empty() ? "" : " ") + sentence.text;
      const std::size_t take = std::min(kPieceSamples - piece.size(), sentence.samples.size() - offset_);
      piece.insert(piece.end(), sentence.samples.begin() + static_cast<std::ptrdiff_t>(offset_),
                   sentence.samples.begin() + static_cast<std::ptrdiff_t>(offset_ + take));
      offset_ += take;
      if (offset_ == sentence.samples.size()) {
        offset_ = 0;
        ++sentence_;
      }
    }
    return speech::pcm_s16le_bytes(piece);
  }

  /// Piece `k` leaves now.
  void sent(std::size_t k) {
    sent_ns_[k].store(std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start_).count(),
                      std::memory_order_release);
    pieces_sent_.store(k + 1, std::memory_order_release);
  }

  /// On gRPC's thread: a message of the stream.
  void received(const client::v1::TrackMessage& message) {
    const std::int64_t now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start_).count();
    std::lock_guard lock(mutex_);
    if (message.has_summary()) summary_frames_ = message.summary().frames();
    if (!message.has_frames()) return;
    const std::size_t sent = pieces_sent_.load(std::memory_order_acquire);
    for (const std::int64_t t_us : message.frames().t_us()) {
      in_order_ = in_order_ && t_us > last_t_us_;
      last_t_us_ = t_us;
      ++frames_;
      const auto k = static_cast<std::size_t>(t_us / kPieceUs);
      if (k >= sent) continue;  // a frame after the audio (the covering silence)
      const std::int64_t latency_us = (now_ns - sent_ns_[k].load(std::memory_order_acquire)) / 1000;
      latencies_us_.push_back(static_cast<std::int32_t>(std::clamp<std::int64_t>(latency_us, 0, INT32_MAX)));
    }
  }

  std::unique_ptr<client::ListenCall> call;
  grpc::Status status;

  /// Whether the stream came back whole (see the file's comment), its audio lasting `audio_us`.
  bool whole(std::int64_t audio_us, std::int64_t frame_period_us) {
    std::lock_guard lock(mutex_);
    return status.ok() && in_order_ && frames_ > 0 && summary_frames_ == frames_ &&
           last_t_us_ >= audio_us - frame_period_us;
  }
  std::vector<std::int32_t> take_latencies() {
    std::lock_guard lock(mutex_);
    return std::move(latencies_us_);
  }
  std::uint64_t frames() {
    std::lock_guard lock(mutex_);
    return frames_;
  }

 private:
  std::size_t sentence_;
  std::size_t offset_ = 0;
  std::vector<std::atomic<std::int64_t>> sent_ns_;
  std::atomic<std::size_t> pieces_sent_ = 0;
  Clock::time_point start_;
  std::mutex mutex_;
  std::vector<std::int32_t> latencies_us_;
  std::uint64_t frames_ = 0;
  std::uint64_t summary_frames_ = 0;
  std::int64_t last_t_us_ = -1;
  bool in_order_ = true;
};

struct ListenLoadConfig {
  std::string address;
  client::ClientOptions client_options;
  int streams = 10;
  std::chrono::seconds duration{10};
  bool transcript = false;
  int latency_ms = 200;
  bool latency_given = false;
};

ListenLoadConfig parse_config(const Arguments& arguments) {
  if (!arguments.positional().empty()) {
    throw UsageError("loadtest takes no arguments, got '" + arguments.positional().front() + "'");
  }
  for (const char* option : {"subscribers-per-session", "fast", "phonemes-per-utterance", "seed", "connections",
                             "client", "no-verify", "mesh-share", "mesh-subdivision", "mesh-encoding", "mesh-solve"}) {
    if (arguments.value(option) || arguments.flag(option)) {
      throw UsageError(std::string("--") + option + ": not an option of --listen (live voices through gRPC's client)");
    }
  }
  ListenLoadConfig config;
  config.address = loopback_server_address(arguments);
  config.client_options = connection_options(arguments);
  config.streams = parse_int_option("producers", arguments.value("producers").value_or("10"), 1, 1000);
  config.duration =
      std::chrono::seconds(parse_int_option("duration", arguments.value("duration").value_or("10"), 1, 3600));
  config.transcript = arguments.flag("transcript");
  if (const auto latency = arguments.value("latency-ms")) {
    config.latency_ms = parse_int_option("latency-ms", *latency, 100, 2000);
    config.latency_given = true;
  }
  return config;
}

}  // namespace

int run_listen_load(const Arguments& arguments) {
  const ListenLoadConfig config = parse_config(arguments);
  const std::vector<Sentence> sentences = speak_sentences();
  const auto pieces = static_cast<std::size_t>(config.duration / std::chrono::microseconds(kPieceUs));
  const std::int64_t audio_us = static_cast<std::int64_t>(pieces) * kPieceUs;

  client::ClientOptions options = config.client_options;
  options.stream_timeout = config.duration + kGrace;
  const client::AnimationClient connection(config.address, options);
  connection.wait_connected();

  client::v1::ListenSettings settings;
  settings.set_encoding(client::v1::AUDIO_ENCODING_PCM_S16LE);
  settings.set_sample_rate_hz(kRateHz);
  if (config.transcript) settings.set_transcript("");
  if (config.latency_given) settings.set_latency_ms(static_cast<std::uint32_t>(config.latency_ms));
  const std::int64_t frame_period_us = 1'000'000 / 30;

  const Clock::time_point start = Clock::now();
  const double cpu_before = process_cpu_seconds();
  std::vector<std::unique_ptr<Voice>> voices;
  for (int s = 0; s < config.streams; ++s) {
    voices.push_back(std::make_unique<Voice>(static_cast<std::size_t>(s), pieces, start));
    Voice& voice = *voices.back();
    voice.call = connection.start_listen(
        settings, [&voice](const client::v1::TrackMessage& message) { voice.received(message); });
  }
  // Stream s's piece k leaves at start + s/N of a second + k pieces; all from this thread.
  const auto offset = [&](int s) { return std::chrono::microseconds(1'000'000LL * s / config.streams); };
  for (std::size_t k = 0; k < pieces; ++k) {
    for (int s = 0; s < config.streams; ++s) {
      Voice& voice = *voices[static_cast<std::size_t>(s)];
      std::this_thread::sleep_until(start + offset(s) +
                                    std::chrono::microseconds(kPieceUs * static_cast<std::int64_t>(k)));
      std::string words;
      std::string piece = voice.next_piece(sentences, words);
      if (config.transcript && !words.empty()) {
        client::v1::ListenWords message;
        message.set_text(words);
        voice.call->send_words(std::move(message));
      }
      voice.sent(k);
      voice.call->send_audio(std::move(piece));
    }
  }
  for (const auto& voice : voices) voice->call->end();
  std::map<std::string, int> errors;
  std::vector<std::int32_t> latencies;
  std::vector<double> stream_p95_ms;
  int whole = 0;
  std::uint64_t frames = 0;
  for (const auto& voice : voices) {
    voice->status = voice->call->wait();
    if (!voice->status.ok()) ++errors[std::string(client::status_code_name(voice->status.error_code()))];
    whole += voice->whole(audio_us, frame_period_us) ? 1 : 0;
    frames += voice->frames();
    std::vector<std::int32_t> own = voice->take_latencies();
    latencies.insert(latencies.end(), own.begin(), own.end());
    stream_p95_ms.push_back(percentiles(own).p95_ms);
  }
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  const double generator_cpu = (process_cpu_seconds() - cpu_before) / seconds;
  const std::size_t measured = latencies.size();
  const auto within = static_cast<std::size_t>(std::count_if(
      latencies.begin(), latencies.end(), [&](std::int32_t us) { return us <= config.latency_ms * 1000; }));
  const Percentiles latency = percentiles(latencies);
  const double worst_p95_ms = stream_p95_ms.empty() ? 0 : *std::max_element(stream_p95_ms.begin(), stream_p95_ms.end());
  const double within_share = measured == 0 ? 0 : 100.0 * static_cast<double>(within) / static_cast<double>(measured);
  const bool ok = errors.empty() && whole == config.streams;

  if (arguments.flag("json")) {
    nlohmann::json report = {{"server", config.address},
                             {"mode", "listen"},
                             {"streams", config.streams},
                             {"transcript", config.transcript},
                             {"latency_budget_ms", config.latency_ms},
                             {"duration_s", config.duration.count()},
                             {"elapsed_s", seconds},
                             {"audio_s", static_cast<double>(audio_us) * 1e-6 * config.streams},
                             {"frames", frames},
                             {"streams_whole", whole},
                             {"latency_ms", to_json(latency)},
                             {"worst_stream_p95_ms", worst_p95_ms},
                             {"within_budget_percent", within_share},
                             {"generator_cpu_cores", generator_cpu},
                             {"errors", errors},
                             {"ok", ok}};
    std::cout << report.dump(2) << '\n';
  } else {
    char line[256];
    std::snprintf(line, sizeof line,
                  "listen load: %d live voices (espeak-ng speech, %d Hz, %lld ms pieces at a speaker's pace) for "
                  "%lld s, %s, latency budget %d ms\n",
                  config.streams, kRateHz, static_cast<long long>(kPieceUs / 1000),
                  static_cast<long long>(config.duration.count()),
                  config.transcript ? "with transcripts sent ahead of their audio" : "audio alone", config.latency_ms);
    std::cout << line;
    std::snprintf(line, sizeof line, "streams: %d of %d whole (ended OK, every frame, in order, to the audio's end)\n",
                  whole, config.streams);
    std::cout << line << "frames: " << frames << " received\n";
    std::cout << "latency, end of the piece holding a frame's time to its arrival: " << to_text(latency) << '\n';
    std::snprintf(line, sizeof line, "worst stream's p95: %.2f ms; frames within the budget: %.1f %%\n", worst_p95_ms,
                  within_share);
    std::cout << line;
    std::snprintf(line, sizeof line, "load generator CPU: %.2f cores\n", generator_cpu);
    std::cout << line << "errors:";
    if (errors.empty()) std::cout << " none";
    for (const auto& [code, count] : errors) std::cout << ' ' << code << ' ' << count;
    std::cout << '\n' << (ok ? "result: every stream whole\n" : "result: FAILED (errors or streams not whole)\n");
  }
  return ok ? 0 : kExitInputError;
}

}  // namespace lipsync::cli
