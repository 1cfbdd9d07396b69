// `lipsync listen SPEECH.wav|-`: sends speech to lipsyncd over a Listen stream and writes the
// frames that come back.
//
// A WAV file goes as 16-bit mono PCM pieces of --piece-ms (any WAV `lipsync render` reads,
// decoded here), as fast as the server takes them (--pace asap, the default for a file) or at the
// pace it was recorded (--pace realtime: piece k leaves k × --piece-ms after the first, as a
// microphone would give it). `-` reads raw signed 16-bit little-endian samples from standard input
// (--rate, --channels) and sends each piece as soon as it is read, so
//   arecord -f S16_LE -r 16000 -c 1 | lipsync listen - --rate 16000 --session me
// is a live microphone. --recording sends the WAV whole (as a file, in pieces of at most 1 MiB):
// the server aligns it as `lipsync render X.wav` does and the track equals that command's, frame
// for frame.
//
// --word-times reads a TTS's word marks (Amazon Polly speech marks, an ElevenLabs alignment, Azure
// word boundaries: lipsync/word_marks.hpp): the stream starts with an empty transcript and each
// word goes as a ListenWords message kWordLeadUs before the audio reaches its start, as a TTS
// hands out its marks with (or before) the audio; with --recording the words are the transcript.
//
// With --pace realtime (or standard input) the latency a user sees is measured here: for each
// frame, from the moment the piece of audio that holds its time was sent to the moment the frame
// arrived; its median, 95th percentile and maximum go to standard error when the stream ends.
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <mutex>
#include <thread>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "files.hpp"
#include "lipsync/error.hpp"
#include "lipsync/model.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/viseme_writer.hpp"
#include "lipsync/visemes.hpp"
#include "lipsync/word_marks.hpp"
#include "network.hpp"
#include "pipeline.hpp"
#include "received_track_writer.hpp"
#include "speech_input.hpp"

namespace lipsync::cli {
namespace {

/// --timeout: a live stream lasts as long as its speech.
constexpr IntSetting kListenTimeoutSetting = {1, 604'800, 86'400};
/// --latency-ms: the server's range and default.
constexpr IntSetting kLatencySetting = {100, 2000, 200};
/// --piece-ms: audio per message.
constexpr IntSetting kPieceSetting = {5, 1000, 20};
/// --rate of standard input.
constexpr IntSetting kSampleRateSetting = {8000, 48000, 16000};
/// A --recording WAV goes in pieces of this size: within lipsyncd's default message limit (4 MiB).
constexpr std::size_t kRecordingPieceBytes = 1024 * 1024;
/// --word-times: a word goes this long before the audio reaches its start.
constexpr std::int64_t kWordLeadUs = 1'000'000;
/// --word-times: the most bytes of words one ListenWords message holds (the server's limit).
constexpr std::size_t kWordsMessageBytes = 16 * 1024;

constexpr auto kOptions = join(kConnectionOptions, std::to_array<OptionSpec>({
    kTrackOutputOption,
    {"format", 0, "FORMAT",
     kJoinedText<"track format: ", kNameList<kTrackFormats, ListStyle::commas_noted>, ", or visemes: ",
                 kNameList<kVisemeFormats, ListStyle::commas_noted>, " (visemes need the built-in model)">
         .view(),
     "json"},
    kSessionOption,
    {"pace", 0, "PACE", "realtime (each piece when its time comes, as a microphone gives it) or asap",
     "asap for a file; standard input is sent as it is read"},
    {"rate", 0, "HZ", kRangedHelp<"sample rate of raw audio on standard input", kSampleRateSetting>.view(),
     kDefaultText<kSampleRateSetting>.view()},
    {"channels", 0, "N", "channels of raw audio on standard input, 1 or 2 (mixed down by the server)", "1"},
    kTextOption,
    kTextFileOption,
    {"word-times", 0, "FILE",
     "the words with the times a TTS gave them (Amazon Polly speech marks, an ElevenLabs alignment, Azure word "
     "boundaries), sent as the audio goes",
     "none"},
    {"voice", 0, "NAME",
     "language of the speech, an espeak-ng voice (lipsync voices); other than English it needs --text or --text-file",
     "English"},
    {"latency-ms", 0, "MS",
     kRangedHelp<"how far a frame may trail the audio it shows (the server's latency budget)", kLatencySetting>
         .view(),
     kDefaultText<kLatencySetting>.view()},
    {"recording", 0, "", "send a WAV whole: frames after its end, equal to 'lipsync render SPEECH.wav'", ""},
    {"piece-ms", 0, "MS", kRangedHelp<"audio per message", kPieceSetting>.view(), kDefaultText<kPieceSetting>.view()},
    kFpsOption,
    kServerModelOption,
    kTimeoutOption<"give up when the stream has not finished after S seconds", kListenTimeoutSetting>,
}));

constexpr std::string_view kUsage = "lipsync listen SPEECH.wav|- [options]";
constexpr std::string_view kDescription =
    "Sends speech to lipsyncd over a Listen stream (a WAV file, or raw 16-bit PCM on\n"
    "standard input: a microphone through arecord) and writes the frames it sends back\n"
    "while the speech is still arriving. With --recording the track equals\n"
    "'lipsync render SPEECH.wav' frame for frame.";

/// When each piece left and how far it took the audio.
struct SentPiece {
  std::int64_t end_us;  // utterance time of the piece's end
  std::chrono::steady_clock::time_point sent;
};

/// Per frame: arrival minus the send time of the piece holding the frame's time, ms.
class LatencyMeter {
 public:
  void sent(std::int64_t end_us) {
    std::lock_guard lock(mutex_);
    pieces_.push_back({end_us, std::chrono::steady_clock::now()});
  }
  void received(const client::v1::TrackMessage& message) {
    if (!message.has_frames()) return;
    const auto now = std::chrono::steady_clock::now();
    std::lock_guard lock(mutex_);
    for (const std::int64_t t_us : message.frames().t_us()) {
      const auto piece = std::upper_bound(pieces_.begin(), pieces_.end(), t_us,
                                          [](std::int64_t t, const SentPiece& p) { return t < p.end_us; });
      if (piece == pieces_.end()) continue;  // a frame after the audio (the covering silence)
      latencies_ms_.push_back(std::chrono::duration<double, std::milli>(now - piece->sent).count());
    }
  }
  /// "p50 … ms, p95 … ms, max … ms over N frames", or "" when no frame was measured.
  std::string report() {
    std::lock_guard lock(mutex_);
    if (latencies_ms_.empty()) return "";
    std::sort(latencies_ms_.begin(), latencies_ms_.end());
    const auto at = [&](double q) {
      return latencies_ms_[std::min(latencies_ms_.size() - 1,
                                    static_cast<std::size_t>(q * static_cast<double>(latencies_ms_.size())))];
    };
    char text[160];
    std::snprintf(text, sizeof text, "p50 %.0f ms, p95 %.0f ms, max %.0f ms over %zu frames", at(0.5), at(0.95),
                  latencies_ms_.back(), latencies_ms_.size());
    return text;
  }

 private:
  std::mutex mutex_;
  std::vector<SentPiece> pieces_;
  std::vector<double> latencies_ms_;
};

}  // namespace

int run_listen(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "listen");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (arguments.positional().size() != 1) {
    throw UsageError(
        "listen needs exactly one SPEECH.wav (or - for raw audio on standard input) "
        "(see 'lipsync listen --help')");
  }
  const std::string& input = arguments.positional().front();
  const bool from_stdin = input == "-";
  const std::string address = server_address(arguments);
  const std::string output = arguments.value("output").value_or("-");
  const RenderFormat output_format = parse_render_format_option(arguments.value("format").value_or("json"));
  if (output_format.moho_switch) throw UsageError("--format: moho-dat is written by 'lipsync render' only");
  // The frames come as channels; a viseme format is computed from them here, with the built-in model.
  const TrackFormat format = output_format.track.value_or(TrackFormat::json);
  const int timeout_s = parse_setting_option(arguments, "timeout", kListenTimeoutSetting);
  const int piece_ms = parse_setting_option(arguments, "piece-ms", kPieceSetting);
  const bool recording = arguments.flag("recording");
  const std::string pace = arguments.value("pace").value_or("asap");
  if (pace != "asap" && pace != "realtime") throw UsageError("--pace: '" + pace + "' is not a pace (realtime or asap)");
  if (from_stdin && arguments.value("pace")) throw UsageError("--pace: standard input is sent as it is read");
  if (!from_stdin && (arguments.value("rate") || arguments.value("channels"))) {
    throw UsageError("--rate and --channels describe raw audio on standard input; a WAV file's header says them");
  }
  if (recording && arguments.value("latency-ms")) {
    throw UsageError("--latency-ms: a recording's frames come after its end; leave it out with --recording");
  }

  client::v1::ListenSettings settings;
  client::v1::AnimationSettings& animation = *settings.mutable_animation();
  animation.set_fps(static_cast<std::uint32_t>(parse_render_plan(arguments).render.fps));
  set_track_request_options(arguments, format, animation);
  if (const auto transcript = transcript_option(arguments)) settings.set_transcript(*transcript);
  std::vector<TimedWord> marks;
  if (const auto marks_file = arguments.value("word-times")) {
    if (settings.has_transcript()) throw UsageError("--word-times: the words are the transcript; leave out --text");
    marks = read_word_marks(read_file(*marks_file), *marks_file);
    settings.set_transcript("");
    if (recording) {
      for (const TimedWord& mark : marks) settings.mutable_transcript()->append(mark.text + " ");
      marks.clear();
    }
  }
  if (const auto voice = arguments.value("voice")) settings.set_voice(*voice);
  if (arguments.value("latency-ms")) {
    settings.set_latency_ms(static_cast<std::uint32_t>(parse_setting_option(arguments, "latency-ms", kLatencySetting)));
  }
  settings.set_recording(recording);
  const int latency_ms = settings.has_latency_ms() ? static_cast<int>(settings.latency_ms())
                                                   : static_cast<int>(kLatencySetting.default_value);

  // The audio: a WAV file read whole (decoded here unless it goes whole), or standard input.
  std::string wav_bytes;
  speech::PcmAudio audio;
  int channels = 1;
  if (from_stdin) {
    audio.sample_rate_hz = parse_setting_option(arguments, "rate", kSampleRateSetting);
    channels = parse_int_option("channels", arguments.value("channels").value_or("1"), 1, 2);
    settings.set_encoding(client::v1::AUDIO_ENCODING_PCM_S16LE);
    settings.set_sample_rate_hz(static_cast<std::uint32_t>(audio.sample_rate_hz));
    settings.set_channels(static_cast<std::uint32_t>(channels));
  } else {
    wav_bytes = read_file(input);
    speech::DecodedWav wav = speech::decode_wav(wav_bytes, input);
    audio = std::move(wav.audio);
    if (recording) {
      settings.set_encoding(client::v1::AUDIO_ENCODING_WAV);
    } else {
      settings.set_encoding(client::v1::AUDIO_ENCODING_PCM_S16LE);
      settings.set_sample_rate_hz(static_cast<std::uint32_t>(audio.sample_rate_hz));
      settings.set_channels(1);
    }
  }
  if (!animation.session().empty()) {
    // Utterance time 0 plays when the first piece leaves plus the budget and a margin: the frames
    // then reach the session's players before they are due.
    animation.mutable_media_clock()->set_clock("unix");
    animation.mutable_media_clock()->set_utterance_zero_us(unix_now_us() + (latency_ms + 100) * 1000LL);
  }

  client::ClientOptions client_options = connection_options(arguments);
  client_options.stream_timeout = std::chrono::seconds(timeout_s);
  const client::AnimationClient connection(address, client_options);
  connection.wait_connected();

  client::ReceivedTrack received;
  std::mutex received_mutex;
  LatencyMeter meter;
  const bool measure = !recording && (from_stdin || pace == "realtime");
  auto call = connection.start_listen(settings, [&](const client::v1::TrackMessage& message) {
    if (measure) meter.received(message);
    std::lock_guard lock(received_mutex);
    received.add(message);
  });

  // The words starting before `audio_end_us` plus the lead, not sent yet, in messages within the limit.
  std::size_t next_mark = 0;
  const auto send_words_before = [&](std::int64_t audio_end_us) {
    while (next_mark < marks.size() && marks[next_mark].start_us < audio_end_us + kWordLeadUs) {
      client::v1::ListenWords words;
      std::size_t bytes = 0;
      for (; next_mark < marks.size() && marks[next_mark].start_us < audio_end_us + kWordLeadUs; ++next_mark) {
        if (words.timed_size() > 0 && bytes + marks[next_mark].text.size() > kWordsMessageBytes) break;
        bytes += marks[next_mark].text.size();
        client::v1::TimedWord& word = *words.add_timed();
        word.set_text(marks[next_mark].text);
        word.set_start_us(marks[next_mark].start_us);
      }
      if (!call->send_words(std::move(words))) return false;
    }
    return true;
  };

  const auto piece_samples = static_cast<std::size_t>(std::max(1, audio.sample_rate_hz * piece_ms / 1000));
  const auto start = std::chrono::steady_clock::now();
  send_words_before(0);  // a stream that has ended already fails its first audio below
  if (recording && !from_stdin) {
    for (std::size_t offset = 0; offset < wav_bytes.size(); offset += kRecordingPieceBytes) {
      if (!call->send_audio(wav_bytes.substr(offset, kRecordingPieceBytes))) break;
    }
  } else if (from_stdin) {
    // Each piece as soon as it is read: arecord gives it at the microphone's pace.
    const std::size_t piece_bytes = piece_samples * 2 * static_cast<std::size_t>(channels);
    std::string piece(piece_bytes, '\0');
    std::uint64_t frames_sent = 0;
    for (;;) {
      std::size_t filled = 0;
      while (filled < piece_bytes) {
        const ssize_t n = ::read(STDIN_FILENO, piece.data() + filled, piece_bytes - filled);
        if (n <= 0) break;
        filled += static_cast<std::size_t>(n);
      }
      if (filled == 0) break;
      frames_sent += filled / (2 * static_cast<std::size_t>(channels));
      const auto end_us =
          static_cast<std::int64_t>(frames_sent * 1'000'000 / static_cast<std::uint64_t>(audio.sample_rate_hz));
      meter.sent(end_us);
      if (!send_words_before(end_us) || !call->send_audio(piece.substr(0, filled))) break;
      if (filled < piece_bytes) break;
    }
  } else {
    for (std::size_t first = 0; first < audio.samples.size(); first += piece_samples) {
      const std::size_t count = std::min(piece_samples, audio.samples.size() - first);
      const auto end_us =
          static_cast<std::int64_t>((first + count) * 1'000'000 / static_cast<std::size_t>(audio.sample_rate_hz));
      if (pace == "realtime") std::this_thread::sleep_until(start + std::chrono::microseconds(end_us));
      meter.sent(end_us);
      if (!send_words_before(end_us) ||
          !call->send_audio(speech::pcm_s16le_bytes(std::span(audio.samples).subspan(first, count)))) {
        break;
      }
    }
  }
  call->end();
  const grpc::Status status = call->wait();
  if (!status.ok()) throw client::CallError("Listen on " + address, status.error_code(), status.error_message());
  if (measure) {
    if (const std::string report = meter.report(); !report.empty()) {
      std::cerr << "lipsync: listen: latency from the end of the piece holding a frame's time to its arrival: "
                << report << '\n';
    }
  }
  std::lock_guard lock(received_mutex);
  if (received.summary) {
    for (const std::string& note : received.summary->notes()) std::cerr << "lipsync: listen: note: " << note << '\n';
  }
  if (output_format.visemes) {
    // The visemes of the frames received, classified as `lipsync render` classifies its own.
    const ArticulationModel& model = ArticulationModel::builtin();
    const bool builtin_channels = std::equal(
        received.header.channels().begin(), received.header.channels().end(), model.channels().begin(),
        model.channels().end(), [](const std::string& name, const auto& channel) { return name == channel.name; });
    if (!builtin_channels) {
      throw InputError("lipsyncd at " + address, 0,
                       "--format " + std::string(arguments.value("format").value_or("")) + ": the server's model '" +
                           received.header.model() +
                           "' is not the built-in one, whose channels the visemes are classified from");
    }
    VisemeOptions options;
    options.vocabulary = vocabulary_of(*output_format.visemes);
    const std::int64_t end_us = received.summary ? received.summary->duration_us() : 0;
    write_viseme_output(received.track, model, options, *output_format.visemes, end_us, output);
    return 0;
  }
  write_received_track(received, format, output, "lipsyncd at " + address);
  return 0;
}

}  // namespace lipsync::cli
