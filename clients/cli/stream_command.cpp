// `lipsync stream INPUT`: sends a timed phoneme file to lipsyncd over an
// Animate stream and writes the frames that come back.
//
// The file goes through the same reading and phone-set steps as `lipsync
// render`, and the frames go through the same writers, so with the default
// settings the output equals `lipsync render INPUT` byte for byte. The frames
// are written with the names the server's TrackHeader gives (its model, channels
// and ARKit weights), so --server-model can pick any model the server loaded.
//
// --realtime sends each chunk when the start time of its last phoneme arrives
// on a steady clock started at the first send (and the end marker at the end
// of the last phoneme), as a TTS front-end would; --fast sends everything at
// once. The session's media clock says utterance time 0 plays
// --playout-delay after the stream starts, on the "unix" clock; by default
// that is the lookahead's release delay on read speech (release_delay.hpp)
// plus a margin, so that players on that clock get every frame in time.
//
// --visemes VOCABULARY and --viewer-mesh (its solve: --mesh-solve) add the server's viseme
// events and its simulated face to what the session's subscribers and viewers get (the track written here
// stays the channels and ARKit weights).
//
// --audio FILE.wav attaches the utterance's sound to the session (AudioAttachment
// pieces of kAudioPieceBytes, sent after the settings and before the first
// phonemes): the session's viewers play it from lipsyncd (/audio?session=NAME)
// with no second server.
#include <algorithm>
#include <array>
#include <chrono>
#include <iostream>
#include <mutex>
#include <thread>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "files.hpp"
#include "lipsync/error.hpp"
#include "lipsync/release_delay.hpp"
#include "lipsync/speech/audio.hpp"
#include "network.hpp"
#include "pipeline.hpp"
#include "received_track_writer.hpp"

namespace lipsync::cli {
namespace {

/// --timeout: a stream in real time lasts as long as its speech.
constexpr IntSetting kStreamTimeoutSetting = {1, 86'400, 3600};

// On top of the lookahead's release delay: the network, scheduling and the
// player's own margin (PlaybackBuffer::kDefaultReleaseMarginUs), ms.
constexpr int kPlayoutMarginMs = 250;
/// --playout-delay, ms; its default_value is the default at the exact lookahead (the help quotes it).
constexpr IntSetting kPlayoutDelaySetting = {
    0, 600'000, static_cast<int>(read_speech_release_delay_us(kLookaheadSetting.max) / 1000) + kPlayoutMarginMs};

constexpr auto kOptions = join(kConnectionOptions, std::to_array<OptionSpec>({
    kTrackOutputOption,
    kTrackFormatOption,
    {"realtime", 0, "", "send each phoneme when its start time arrives (the default)", ""},
    {"fast", 0, "", "send all phonemes as fast as possible", ""},
    {"chunk", 0, "N", "phonemes per message, 1 to 10000", "1"},
    kServerModelOption,
    kSessionOption,
    {"audio", 0, "FILE.wav",
     "attach the utterance's sound (a WAV file) to the session: its viewers play it from lipsyncd (needs --session)",
     ""},
    kVisemesOption,
    {"viewer-mesh", 0, "",
     "also publish the server's simulated face (its vertices, every frame) for the session's viewers (needs --session)",
     "off"},
    {"mesh-solve", 0, "full|fast",
     "the --viewer-mesh face's solve: fast takes about 0.45 of the server's CPU, closures sealed (docs/face.md, "
     "\"Solves\")",
     "full"},
    {"playout-delay", 0, "MS",
     kRangedHelp<"media clock: utterance time 0 plays this long after the stream starts", kPlayoutDelaySetting>.view(),
     kJoinedText<"the lookahead's release delay on read speech + ", kDefaultText<IntSetting{0, 0, kPlayoutMarginMs}>,
                 " (", kDefaultText<kPlayoutDelaySetting>, " at lookahead ",
                 kDefaultText<IntSetting{0, 0, kLookaheadSetting.max}>, ")">
         .view()},
    kFpsOption,
    kPhoneSetOption,
    kInputFormatOption,
    kTierOption,
    kSampleRateOption,
    {"lookahead", 0, "N",
     kRangedHelp<"segments after a frame's own that must be known before it is sent", kLookaheadSetting,
                 " (the maximum is exact)">.view(),
     kDefaultText<kLookaheadSetting>.view()},
    kTimeoutOption<"give up when the stream has not finished after S seconds", kStreamTimeoutSetting>,
}));

// --audio is sent in pieces of this size: well within lipsyncd's default message limit (4 MiB).
constexpr std::size_t kAudioPieceBytes = 1024 * 1024;

constexpr std::string_view kUsage = "lipsync stream INPUT [options]";
constexpr std::string_view kDescription =
    "Streams a timed phoneme file (INPUT, or - for standard input) to lipsyncd over one\n"
    "Animate stream and writes the frames it sends back, named after the server's model\n"
    "(its channels and ARKit weights). With the default settings the track equals\n"
    "'lipsync render INPUT' byte for byte.";

}  // namespace

int run_stream(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "stream");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (arguments.positional().size() != 1) {
    throw UsageError("stream needs exactly one INPUT file (or - for standard input) (see 'lipsync stream --help')");
  }
  const std::string& input = arguments.positional().front();
  const std::string address = server_address(arguments);
  const std::string output = arguments.value("output").value_or("-");
  const TrackFormat format = parse_track_format_option(arguments.value("format").value_or("json"));
  if (arguments.flag("realtime") && arguments.flag("fast")) throw UsageError("choose one of --realtime and --fast");
  const bool realtime = !arguments.flag("fast");
  const int chunk_size = parse_int_option("chunk", arguments.value("chunk").value_or("1"), 1, 10'000);
  const int timeout_s = parse_setting_option(arguments, "timeout", kStreamTimeoutSetting);

  std::optional<InputFormat> input_format;
  if (const auto text = arguments.value("input-format")) input_format = parse_input_format_option(*text);
  const ParseOptions parse_options = parse_options_from(arguments);
  const RenderPlan plan = parse_render_plan(arguments);
  const int delay_ms =
      arguments.value("playout-delay")
          ? parse_int_option("playout-delay", *arguments.value("playout-delay"), kPlayoutDelaySetting.min,
                             kPlayoutDelaySetting.max)
          : static_cast<int>(read_speech_release_delay_us(plan.render.lookahead) / 1000) + kPlayoutMarginMs;
  client::v1::AnimationSettings settings;
  settings.set_fps(static_cast<std::uint32_t>(plan.render.fps));
  if (arguments.value("lookahead")) settings.set_lookahead(static_cast<std::uint32_t>(plan.render.lookahead));
  set_track_request_options(arguments, format, settings);
  set_viseme_request_option(arguments, settings);
  if (arguments.flag("viewer-mesh")) {
    if (settings.session().empty())
      throw UsageError("--viewer-mesh needs --session: the face goes to the session's viewers");
    settings.mutable_outputs()->mutable_mesh()->set_enabled(true);
  }
  if (const auto solve = arguments.value("mesh-solve")) {
    if (!arguments.flag("viewer-mesh")) throw UsageError("--mesh-solve needs --viewer-mesh");
    settings.mutable_outputs()->mutable_mesh()->set_solve(
        parse_fast_mesh_solve_option(*solve) ? client::v1::MESH_SOLVE_FAST : client::v1::MESH_SOLVE_FULL);
  }
  const std::optional<std::string> phone_set_name = arguments.value("phone-set");
  if (phone_set_name && phone_set_name->empty()) throw UsageError("--phone-set: the name must not be empty");

  // The phone set is chosen (or detected) against the built-in model's inventory
  // and sent by name; the server resolves it against its own model.
  const ArticulationModel& model = ArticulationModel::builtin();
  const std::string content = read_file(input);
  const std::string source = input == "-" ? std::string(kStdinName) : input;
  const InputFormat chosen_format = input_format ? *input_format : detect_input_format(source, content);
  const LabeledUtterance utterance = parse_utterance(content, chosen_format, source, parse_options);
  if (utterance.intervals.empty()) throw InputError(source, 0, "the utterance has no phonemes");
  std::vector<PhoneSet> candidates;
  settings.set_phone_set(choose_phone_set(phone_set_name, utterance, model, candidates).name());
  std::string audio;
  if (const auto audio_path = arguments.value("audio")) {
    if (settings.session().empty()) throw UsageError("--audio needs --session: only a session keeps its audio");
    audio = read_file(*audio_path);
    (void)speech::wav_layout_and_duration_us(audio, *audio_path);  // a file lipsyncd would refuse fails here
  }

  client::ClientOptions client_options = connection_options(arguments);
  client_options.stream_timeout = std::chrono::seconds(timeout_s);
  const client::AnimationClient connection(address, client_options);
  connection.wait_connected();

  client::ReceivedTrack received;
  std::mutex received_mutex;
  const auto start = std::chrono::steady_clock::now();
  settings.mutable_media_clock()->set_clock("unix");
  settings.mutable_media_clock()->set_utterance_zero_us(unix_now_us() + delay_ms * 1000LL);
  auto call = connection.start_animate(settings, [&](const client::v1::TrackMessage& message) {
    std::lock_guard lock(received_mutex);
    received.add(message);
  });
  for (std::size_t offset = 0; offset < audio.size(); offset += kAudioPieceBytes) {
    if (!call->send_audio(audio.substr(offset, kAudioPieceBytes))) break;
  }
  const auto& intervals = utterance.intervals;
  for (std::size_t first = 0; first < intervals.size(); first += static_cast<std::size_t>(chunk_size)) {
    const std::size_t last = std::min(intervals.size(), first + static_cast<std::size_t>(chunk_size));
    if (realtime) std::this_thread::sleep_until(start + std::chrono::microseconds(intervals[last - 1].start_us));
    std::vector<client::v1::Phoneme> chunk;
    for (std::size_t i = first; i < last; ++i) chunk.push_back(client::to_wire(intervals[i]));
    if (!call->send(std::move(chunk))) break;
  }
  if (realtime) std::this_thread::sleep_until(start + std::chrono::microseconds(intervals.back().end_us));
  call->end();
  const grpc::Status status = call->wait();
  if (!status.ok()) throw client::CallError("Animate on " + address, status.error_code(), status.error_message());

  std::lock_guard lock(received_mutex);
  write_received_track(received, format, output, "lipsyncd at " + address);
  return 0;
}

}  // namespace lipsync::cli
