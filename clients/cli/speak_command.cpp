// `lipsync speak TEXT --server ADDR`: lipsyncd speaks the text (its Speak RPC,
// espeak-ng on the server) and sends back the speech and the frames of what it
// spoke; this writes the track (-o, named after the server's model, as `lipsync
// stream` does) and the speech (--wav). With the built-in model and the default
// settings both equal what `lipsync say TEXT -o ... --wav ...` writes on this
// machine, byte for byte (the same espeak-ng, the same render path).
// --session publishes the frames for `lipsync subscribe` / `play` and the browser
// viewer, with --visemes the server's viseme events too. The session's media clock
// says utterance time 0 (the first sample) plays --playout-delay after the call
// starts, on the "unix" clock: time for lipsyncd to speak and for a viewer to fetch
// the voice (/audio) before its first sample is due, so that it plays whole.
#include <array>
#include <chrono>
#include <iostream>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "files.hpp"
#include "lipsync/speech/audio.hpp"
#include "network.hpp"
#include "pipeline.hpp"
#include "received_track_writer.hpp"
#include "speech_input.hpp"

namespace lipsync::cli {
namespace {

/// --timeout: synthesis and rendering of one text.
constexpr IntSetting kSpeakTimeoutSetting = {1, 86'400, 600};
/// --playout-delay, ms: espeak-ng speaks a sentence in tens of milliseconds and a viewer fetches and
/// decodes its voice in tens more, so a second leaves room for a loaded machine (minutes of speech,
/// 10 MB of WAV for the viewer, want more).
constexpr IntSetting kSpeakPlayoutDelaySetting = {0, 600'000, 1000};

constexpr auto kOptions =
    join(kConnectionOptions,
         std::to_array<OptionSpec>({
             kTrackOutputOption,
             kTrackFormatOption,
             {"wav", 0, "FILE", "also write the speech to FILE (16-bit mono PCM WAV at the server's rate, 22050 Hz)",
              "no WAV"},
             kVoiceOption,
             kRateOption,
             kFpsOption,
             kServerModelOption,
             kSessionOption,
             kVisemesOption,
             {"playout-delay", 0, "MS",
              kRangedHelp<"media clock: utterance time 0 (the first sample) plays this long after the call starts",
                          kSpeakPlayoutDelaySetting>
                  .view(),
              kDefaultText<kSpeakPlayoutDelaySetting>.view()},
             kTimeoutOption<"give up when the call has not finished after S seconds", kSpeakTimeoutSetting>,
         }));

constexpr std::string_view kUsage = "lipsync speak TEXT [options]";
constexpr std::string_view kDescription =
    "Asks lipsyncd to speak TEXT (espeak-ng on the server) and writes the animation\n"
    "track of what it spoke, which covers the whole audio, and with --wav the speech.\n"
    "With the default settings both equal 'lipsync say TEXT' byte for byte.";

}  // namespace

int run_speak(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "speak");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (arguments.positional().empty()) throw UsageError("speak needs a TEXT to speak (see 'lipsync speak --help')");
  if (arguments.positional().size() > 1) {
    throw UsageError("speak takes one TEXT (quote it), got also '" + arguments.positional()[1] + "'");
  }
  const std::string address = server_address(arguments);
  const std::string output = arguments.value("output").value_or("-");
  const TrackFormat format = parse_track_format_option(arguments.value("format").value_or("json"));
  const std::optional<std::string> wav_path = arguments.value("wav");
  if (wav_path && (wav_path->empty() || *wav_path == "-")) throw UsageError("--wav: needs a file name");
  const int timeout_s = parse_setting_option(arguments, "timeout", kSpeakTimeoutSetting);
  const speech::SynthesisOptions synthesis = synthesis_options(arguments);

  client::v1::SpeakRequest request;
  request.set_text(arguments.positional().front());
  request.set_voice(synthesis.voice);
  request.set_words_per_minute(static_cast<std::uint32_t>(synthesis.words_per_minute));
  client::v1::AnimationSettings& settings = *request.mutable_settings();
  settings.set_fps(static_cast<std::uint32_t>(parse_render_plan(arguments).render.fps));
  set_track_request_options(arguments, format, settings);
  set_viseme_request_option(arguments, settings);
  const int delay_ms = parse_setting_option(arguments, "playout-delay", kSpeakPlayoutDelaySetting);

  client::ClientOptions client_options = connection_options(arguments);
  client_options.stream_timeout = std::chrono::seconds(timeout_s);
  const client::AnimationClient connection(address, client_options);
  connection.wait_connected();
  settings.mutable_media_clock()->set_clock("unix");
  settings.mutable_media_clock()->set_utterance_zero_us(unix_now_us() + delay_ms * 1000LL);
  const client::SpokenTrack spoken = connection.speak(request);
  if (spoken.summary) {  // how espeak-ng read the text, when that needs saying (words it read in another language...)
    for (const std::string& note : spoken.summary->track().notes()) std::cerr << "lipsync: warning: " << note << '\n';
  }

  // The WAV first: the track, usually what a caller waits for, then appears last.
  if (wav_path) {
    speech::PcmAudio audio;
    audio.sample_rate_hz = static_cast<int>(spoken.header.sample_rate_hz());
    audio.samples = spoken.samples;
    AtomicOutputFile file(*wav_path);
    speech::write_wav(file.stream(), audio);
    file.commit();
  }
  write_received_track(spoken.track, format, output, "lipsyncd at " + address);
  return 0;
}

}  // namespace lipsync::cli
