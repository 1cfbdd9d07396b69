// `lipsync play SESSION`: plays a session's frames in the terminal in real
// time, as a renderer in sync with the audio would.
//
// Frames arrive from a Subscribe stream (on gRPC's threads) into a
// PlaybackBuffer anchored to the session's media clock: the producer's
// utterance_zero_us on the "unix" (wall) or "steady" clock, or, for a clock
// this machine cannot read, the arrival of the first frame. A Boost.Asio
// steady_timer ticks at the display rate; each tick samples the buffer at the
// clock's current reading and draws the mouth (jaw rotation and lip
// compression as bars) with the measured drift: how far the newest frame is
// ahead of the audio (lead) and how late the newest frame arrived for its play
// time (late). Playback ends when the session ends and its last frame played.
//
// The buffer plays later than the media clock (its playout offset) only when
// the server's release delay and per-batch release lag say that frames would
// otherwise arrive after they are due (playback_buffer.hpp); with a producer
// whose playout delay covers the lookahead (lipsync stream's default) the
// offset is 0. The summary line reports it.
#include <unistd.h>

#include <algorithm>
#include <array>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <iostream>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "lipsync/client/playback_buffer.hpp"
#include "network.hpp"
#include "setting_help.hpp"

namespace lipsync::cli {
namespace {

constexpr auto kOptions =
    join(kConnectionOptions,
         std::to_array<OptionSpec>({
             kFromNowOption,
             {"rate", 0, "N", kRangedHelp<"display updates per second", kFpsSetting>.view(), "the track's fps"},
             {"frames", 0, "N", "stop after N display updates, 1 to 10000000", "when the session ends"},
             {"no-tty", 0, "", "print one line per update instead of redrawing one line", "redraw on a terminal"},
             kWaitOption,
         }));

constexpr std::string_view kUsage = "lipsync play SESSION [options]";
constexpr std::string_view kDescription =
    "Plays the frames of SESSION in real time against its media clock, showing the jaw\n"
    "opening and lip compression, the lead of the received frames over the audio clock,\n"
    "how late the newest frame arrived, and underruns.";

constexpr int kBarWidth = 20;

enum class AnchorClock { unix_wall, steady };

/// Everything the gRPC threads and the display timer share.
struct PlayState {
  std::mutex mutex;
  std::optional<client::PlaybackBuffer> buffer;
  AnchorClock clock = AnchorClock::steady;
  bool anchor_on_first_frame = false;
  std::string anchor_text;
  int fps = 30;
  std::int64_t release_delay_us = 0;
  std::vector<int> jaw_channels;
  std::vector<int> lip_channels;
  std::optional<grpc::Status> status;

  std::int64_t now_us() const { return clock == AnchorClock::unix_wall ? unix_now_us() : steady_now_us(); }

  void take(const client::v1::TrackMessage& message) {
    std::lock_guard lock(mutex);
    if (message.has_header()) {
      const auto& header = message.header();
      if (header.channels().empty()) throw std::runtime_error("the session carries no channel values");
      buffer.emplace(static_cast<std::size_t>(header.channels_size()));
      buffer->expect_release_delay(header.release_delay_us());
      release_delay_us = header.release_delay_us();
      fps = header.fps() == 0 ? 30 : static_cast<int>(header.fps());
      for (int c = 0; c < header.channels_size(); ++c) {
        const std::string& name = header.channels(c);
        if (name == "jaw_rotation") jaw_channels.push_back(c);
        if (name.starts_with("orbicularis_oris")) lip_channels.push_back(c);
      }
      const std::string& clock_name = header.media_clock().clock();
      if (clock_name == "unix" || clock_name == "steady") {
        clock = clock_name == "unix" ? AnchorClock::unix_wall : AnchorClock::steady;
        buffer->anchor(header.media_clock().utterance_zero_us());
        anchor_text = "media clock '" + clock_name + "'";
      } else {
        clock = AnchorClock::steady;
        anchor_on_first_frame = true;
        anchor_text = clock_name.empty() ? "first frame (no media clock)"
                                         : "first frame (clock '" + clock_name + "' is not readable here)";
      }
      return;
    }
    if (!message.has_frames() || !buffer) return;
    const auto& batch = message.frames();
    if (batch.t_us_size() == 0) return;
    const std::size_t channels = buffer->channel_count();
    const std::int64_t arrival_us = now_us();
    if (anchor_on_first_frame && !buffer->anchored()) buffer->anchor(arrival_us - batch.t_us(0));
    buffer->note_batch(batch.t_us(0), batch.release_lag_us(), arrival_us);
    for (int i = 0; i < batch.t_us_size(); ++i) {
      const std::span<const float> values(batch.values().data() + static_cast<std::size_t>(i) * channels, channels);
      buffer->push(batch.t_us(i), values, arrival_us);
    }
  }
};

std::string bar(double fraction) {
  const int filled = static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * kBarWidth));
  return std::string(static_cast<std::size_t>(filled), '#') +
         std::string(static_cast<std::size_t>(kBarWidth - filled), '.');
}

double mean_of(const std::vector<float>& values, const std::vector<int>& channels) {
  if (channels.empty()) return 0.0;
  double sum = 0.0;
  for (const int c : channels) sum += values[static_cast<std::size_t>(c)];
  return sum / static_cast<double>(channels.size());
}

std::string milliseconds(std::optional<std::int64_t> us) {
  if (!us) return "   -   ";
  char text[32];
  std::snprintf(text, sizeof text, "%+6.0f ms", static_cast<double>(*us) / 1000.0);
  return text;
}

/// What `lipsync play` was asked for, checked.
struct PlayOptions {
  std::string session;
  std::string address;
  client::v1::SubscribeRequest::Start start{};
  std::optional<int> rate;          ///< display updates per second (--rate; default: the track's fps)
  std::optional<long> max_updates;  ///< --frames: stop after this many display updates
  bool redraw = false;              ///< redraw one line on a terminal (else one line per update)
};

PlayOptions parse_play_options(const Arguments& arguments) {
  if (arguments.positional().size() != 1 || arguments.positional().front().empty()) {
    throw UsageError("play needs exactly one SESSION name (see 'lipsync play --help')");
  }
  PlayOptions options;
  options.session = arguments.positional().front();
  options.address = server_address(arguments);
  options.start = subscribe_start(arguments);
  if (const auto text = arguments.value("rate"))
    options.rate =
        parse_int_option("rate", *text, static_cast<int>(kFpsSetting.min), static_cast<int>(kFpsSetting.max));
  if (const auto text = arguments.value("frames"))
    options.max_updates = parse_int_option("frames", *text, 1, 10'000'000);
  options.redraw = !arguments.flag("no-tty") && ::isatty(STDOUT_FILENO) == 1;
  return options;
}

/// Starts following the session into `state`: its messages and its end come on gRPC's threads.
std::unique_ptr<client::SubscribeCall> follow_session(const client::AnimationClient& connection,
                                                      const PlayOptions& options, PlayState& state) {
  return connection.start_subscribe(
      options.session, options.start, [&state](const client::v1::TrackMessage& message) { state.take(message); },
      [&state](const grpc::Status& status) {
        std::lock_guard lock(state.mutex);
        state.status = status;
        if (state.buffer) state.buffer->finish();
      });
}

/// One display update of an anchored buffer: the line for the media clock's current reading
/// (empty while no frame has come) and whether the session has ended and its last frame played.
struct DisplayUpdate {
  std::string line;
  bool ended = false;
};

/// Samples the buffer at the clock's current reading (into `values`) and draws the mouth and the
/// drift. Under state.mutex.
DisplayUpdate sample_for_display(PlayState& state, std::vector<float>& values) {
  client::PlaybackBuffer& buffer = *state.buffer;
  values.resize(buffer.channel_count());
  const client::PlaybackSample sample = buffer.sample(state.now_us(), values);
  DisplayUpdate update;
  if (sample.state != client::SampleState::no_frames) {
    const double jaw = mean_of(values, state.jaw_channels) / 0.35;  // jaw_rotation: radians, ~0.35 wide open
    const double lips = mean_of(values, state.lip_channels);
    char head[64];
    std::snprintf(head, sizeof head, "t=%8.3f s", static_cast<double>(sample.utterance_us) / 1e6);
    update.line = std::string(head) + "  jaw |" + bar(jaw) + "|  lips |" + bar(lips) + "|  lead " +
                  milliseconds(sample.lead_us) + "  late " + milliseconds(buffer.stats().last_lateness_us) +
                  "  underruns " + std::to_string(buffer.stats().underruns);
  }
  update.ended = sample.state == client::SampleState::ended;
  return update;
}

/// The line after the last update: what played, against which anchor, and how late. Under state.mutex.
void print_summary(const PlayState& state, long updates, bool redraw, std::ostream& out) {
  const auto& stats = state.buffer->stats();
  out << (redraw ? "\n" : "") << "played " << updates << " updates anchored to " << state.anchor_text << ": "
      << stats.frames_pushed << " frames, " << stats.underruns << " underruns, max behind "
      << stats.max_behind_us / 1000 << " ms, max lateness "
      << (stats.max_lateness_us ? std::to_string(*stats.max_lateness_us / 1000) + " ms" : "-") << ", playout offset "
      << state.buffer->playout_offset_us() / 1000 << " ms (release delay " << state.release_delay_us / 1000
      << " ms, max release lag " << stats.max_release_lag_us / 1000 << " ms)\n";
}

/// Follows the session (`subscribe` starts a Subscribe into `state`) and draws it on a steady timer at the
/// display rate until it ends and its last frame played, or --frames updates; a session not started yet is
/// asked for again as --wait says. Returns the status that ended it when that was a failure.
std::optional<grpc::Status> play_session(PlayState& state, const PlayOptions& options, SessionWait& wait,
                                         const std::function<std::unique_ptr<client::SubscribeCall>()>& subscribe) {
  std::unique_ptr<client::SubscribeCall> call = subscribe();
  boost::asio::io_context io;
  boost::asio::steady_timer timer(io);
  long updates = 0;
  std::vector<float> values;
  std::optional<grpc::Status> failure;
  std::function<void()> tick;
  tick = [&] {
    std::string line;
    bool stop = false;
    {
      std::unique_lock lock(state.mutex);
      if (state.status && !state.buffer) {
        const grpc::Status status = *state.status;
        if (wait.asks_again(status.error_code())) {
          state.status.reset();
          lock.unlock();
          call = subscribe();
          lock.lock();
        } else {
          failure =
              status.ok() ? grpc::Status(grpc::StatusCode::INTERNAL, "the session ended without a header") : status;
          stop = true;
        }
      }
      if (!stop && state.buffer && state.buffer->anchored()) {
        DisplayUpdate update = sample_for_display(state, values);
        if (!update.line.empty()) ++updates;
        line = std::move(update.line);
        if (update.ended) {
          stop = true;
          if (state.status && !state.status->ok()) failure = *state.status;
        }
      }
      if (options.max_updates && updates >= *options.max_updates) stop = true;
      if (!line.empty()) {
        std::cout << (options.redraw ? "\r" : "") << line << (options.redraw ? "" : "\n") << std::flush;
      }
      if (stop && state.buffer) print_summary(state, updates, options.redraw, std::cout);
    }
    if (stop) return;
    const int per_second = options.rate.value_or(state.fps);
    timer.expires_at(timer.expiry() + std::chrono::microseconds(1'000'000 / per_second));
    timer.async_wait([&](const boost::system::error_code& error) {
      if (!error) tick();
    });
  };
  timer.expires_after(std::chrono::milliseconds(0));
  timer.async_wait([&](const boost::system::error_code& error) {
    if (!error) tick();
  });
  io.run();
  call.reset();
  return failure;
}

}  // namespace

int run_play(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "play");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  const PlayOptions options = parse_play_options(arguments);
  SessionWait wait(arguments);

  const client::AnimationClient connection(options.address, connection_options(arguments));
  connection.wait_connected();
  wait.start();

  PlayState state;
  const std::optional<grpc::Status> failure =
      play_session(state, options, wait, [&] { return follow_session(connection, options, state); });
  if (failure)
    throw client::CallError("Subscribe to session '" + options.session + "' on " + options.address,
                            failure->error_code(), failure->error_message());
  return 0;
}

}  // namespace lipsync::cli
