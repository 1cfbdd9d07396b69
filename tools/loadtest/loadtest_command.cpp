// `lipsync loadtest`: N concurrent producers stream synthetic utterances to
// lipsyncd back to back for a fixed time, optionally with M subscribers per
// session, and report throughput, latency, errors by status code and whether
// every frame arrived. This file runs the load; loadtest_report.cpp sums up
// and prints what the run counted.
//
// Each utterance (lipsync::synthesize_utterance, ARPAbet) is rendered offline
// first, through the same SegmentBuilder and StreamingRenderer the server
// uses, recording for every frame which phoneme's arrival released it: the
// frame of segment k can be computed once segment k+7 is known (or at the end
// marker). A frame's latency is its arrival time minus the send time of that
// phoneme, so it measures the server and the network, not the lookahead the
// algorithm needs by design. The received frames are checked against the
// offline render (count, times and channel values, bit for bit): "every frame
// arrived" means each utterance that ended OK delivered exactly the offline
// frames, to its producer and to each subscriber.
//
// The check is cheap enough for thousands of streams on one core: a batch is
// compared with the precomputed track as two memory ranges (its times and its
// packed values), not frame by frame, and all its frames get the latency of
// the phoneme that released them (the server releases a batch per phoneme).
// The report includes the generator's own CPU (getrusage), so a run whose
// generator was saturated can be told apart from one that measured the server.
//
// --realtime sends each phoneme when its start time arrives (and the end
// marker at the utterance's end), on a 1 ms grid; --fast sends everything at
// once. All timing runs on one thread with Boost.Asio steady timers. The calls
// go through one of two clients (loadtest_clients.hpp): by default the
// generator's own HTTP/2 client, whose streams all live on that same thread,
// or gRPC's client library (--client grpc). The run is bounded: no utterance
// starts after --duration, and whatever still runs 30 s later is cancelled
// (and counted as CANCELLED). Only loopback servers are accepted.
//
// --mesh-share F asks for the physics face (settings.outputs.mesh) on a share
// F of the producers, spread evenly over them (producer p has it when
// round((p+1)·F) > round(p·F)), with --mesh-subdivision, --mesh-encoding and --mesh-solve.
// Their frames are checked as the others' are, and each frame must also carry
// the positions of the header's vertex count (V × 3 floats, or V × 3 int16).
// The report gives frames and latency for mesh and non-mesh producers (and
// their subscribers) separately, since a mesh stream costs the server a solver.
//
// --no-verify is for servers that send frames of the right shape but not the
// engine's (tests/bench/grpc_baseline_server): frames are counted, not
// checked, and a frame's latency is its arrival time minus the send time of
// the last message sent on the stream before it arrived (for lipsyncd in real
// time that is the same phoneme as above).
#include <absl/synchronization/mutex.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <iostream>
#include <memory>
#include <mutex>

#include "arguments.hpp"
#include "cli_error.hpp"
#include "commands.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/synthetic.hpp"
#include "listen_load.hpp"
#include "loadtest_clients.hpp"
#include "loadtest_report.hpp"
#include "loadtest_shared.hpp"
#include "network.hpp"
#include "pipeline.hpp"

namespace lipsync::cli {
namespace {

namespace asio = boost::asio;
using Clock = std::chrono::steady_clock;

constexpr auto kOptions = join(
    kConnectionOptions,
    std::to_array<OptionSpec>({
        {"producers", 0, "N", "concurrent Animate streams (with --listen: live voices, 1 to 1000), 1 to 10000", "10"},
        {"subscribers-per-session", 0, "M", "subscribers following each producer's session, 0 to 16", "0"},
        {"duration", 0, "S", "seconds during which new utterances start, 1 to 600", "10"},
        {"realtime", 0, "", "send each phoneme when its start time arrives (the default)", ""},
        {"fast", 0, "", "send each utterance as fast as possible", ""},
        {"phonemes-per-utterance", 0, "K", "phonemes per synthetic utterance, 1 to 10000", "30"},
        {"seed", 0, "S", "seed of the synthetic utterances, 0 to 2147483647", "1"},
        {"connections", 0, "N", "HTTP/2 connections the streams are spread over, 1 to 64", "4"},
        {"client", 0, "KIND",
         "h2: the generator's own HTTP/2 client, all streams on one thread (plaintext only); grpc: the gRPC client "
         "library, as applications use it",
         "h2; grpc with --tls, --ca, --cert or --key"},
        {"json", 0, "", "print the report as JSON", ""},
        {"no-verify", 0, "", "count frames without checking them against the offline render (baseline servers)", ""},
        {"mesh-share", 0, "F",
         "fraction of the producers (spread evenly) that ask for the mesh output (physics face), 0 to 1", "0"},
        {"mesh-subdivision", 0, "N",
         kRangedHelp<"subdivision level of their mesh", kMeshSubdivisionSetting, " (1061, 2643, 8903 vertices)">.view(),
         kDefaultText<kMeshSubdivisionSetting>.view()},
        {"mesh-encoding", 0, "ENC", "encoding of their vertex positions: float32 or int16", "float32"},
        {"mesh-solve", 0, "full|fast", "the face's solve (settings.outputs.mesh.solve)", "full"},
        {"listen", 0, "",
         "audio mode: each producer is a live voice, a Listen stream of espeak-ng speech sent at a speaker's pace "
         "(--duration up to 3600)",
         ""},
        {"transcript", 0, "", "with --listen: each sentence's words go ahead of its audio", ""},
        {"latency-ms", 0, "MS", "with --listen: the streams' latency budget, 100 to 2000", "the server's, 200"},
    }));

constexpr std::string_view kUsage = "lipsync loadtest [options]";
constexpr std::string_view kDescription =
    "Load test of a lipsyncd on this machine: N producers stream synthetic utterances\n"
    "back to back for --duration seconds (with M subscribers per session), then a report:\n"
    "frames/s, latency from the moment a frame could be computed to its arrival\n"
    "(p50/p95/p99/max), errors by status code, and whether every frame arrived;\n"
    "with --mesh-share, frames and latency apart for producers with and without the mesh.\n"
    "With --listen, N live voices instead: the latency from the end of a piece of audio to\n"
    "the frame that shows it, and whether every stream came back whole.\n"
    "Exit status 0 when there were no errors and every frame arrived, 1 otherwise.";

constexpr std::size_t kUtterancePool = 64;
constexpr auto kGrace = std::chrono::seconds(30);
constexpr auto kPauseAfterError = std::chrono::milliseconds(100);
/// Real-time sends are due on a 1 ms grid. A wake-up of the generator's thread costs more kernel
/// time than the sends it makes (perf: context switches were most of the generator's CPU at 2,000
/// sessions), so phonemes due in the same millisecond leave together, as a front-end that streams
/// in small bursts would send them. Latency is measured from the actual send, so it is unaffected.
constexpr auto kSendGrid = std::chrono::milliseconds(1);

/// One synthetic utterance and what the server must send for it.
struct Utterance {
  UtteranceRequests requests;              ///< the phonemes, as each client sends them
  std::vector<std::int64_t> frame_t_us;    ///< the offline render's frame times
  std::vector<float> frame_values;         ///< the offline render's channel values, frame-major
  std::vector<std::uint32_t> released_by;  ///< per frame: phoneme index that released it (size() = end marker)
};

Utterance make_utterance(std::uint64_t seed, std::size_t phonemes, const ArticulationModel& model,
                         const PhoneSet& phone_set) {
  SyntheticOptions options;
  options.phonemes = phonemes;
  options.seed = seed;
  std::vector<LabeledInterval> intervals = synthesize_utterance(options);
  Utterance utterance;
  std::vector<client::v1::Phoneme> wire;
  SegmentBuilder builder(model, phone_set, "synthetic utterance");
  StreamingRenderer renderer(model);
  Track streamed;
  streamed.channel_count = model.channel_count();
  std::vector<Segment> segments;
  for (std::size_t i = 0; i < intervals.size(); ++i) {
    intervals[i].line = static_cast<int>(i) + 1;
    wire.push_back(client::to_wire(intervals[i]));
    segments.clear();
    builder.push(intervals[i], segments);
    for (const Segment& segment : segments) renderer.push(segment, streamed);
    utterance.released_by.resize(streamed.frame_count(), static_cast<std::uint32_t>(i));
  }
  renderer.finish(streamed);
  utterance.released_by.resize(streamed.frame_count(), static_cast<std::uint32_t>(intervals.size()));
  LabeledUtterance whole{"synthetic utterance", "arpabet", intervals};
  const Track offline = render_track(model, build_segments(whole, model, phone_set));
  if (offline.t_us != streamed.t_us) throw std::logic_error("streaming and offline renders differ");
  utterance.requests = UtteranceRequests(std::move(wire));
  utterance.frame_t_us = offline.t_us;
  utterance.frame_values = offline.values;
  return utterance;
}

/// What one stream (a producer's Animate or a subscriber) received.
struct StreamTally {
  std::uint64_t frames = 0;
  std::uint64_t batches = 0;            ///< messages that carried frames
  std::uint64_t unexpected = 0;         ///< frames not in the offline render (wrong index or time)
  std::uint64_t without_positions = 0;  ///< mesh stream: frames without the header's V × 3 positions
  std::size_t mesh_coordinates = 0;     ///< from the header: V × 3 (0: no mesh in the header)
  bool mesh_int16 = false;              ///< from the header: positions come as int16
  std::vector<std::int32_t> latencies_us;
};

/// One Animate call of one utterance. Send times are written by the timer
/// thread before each send and read by gRPC threads when frames arrive.
struct Run {
  const Utterance* utterance = nullptr;
  std::unique_ptr<std::atomic<std::int64_t>[]> sent_us;  // per phoneme, then the end marker
  std::atomic<std::int64_t> last_sent_us{0};             // the latest of sent_us (--no-verify)
  Clock::time_point start;
  std::size_t next_phoneme = 0;
  std::unique_ptr<LoadCall> call;
  std::vector<std::unique_ptr<LoadCall>> subscribers;
  std::vector<std::unique_ptr<StreamTally>> subscriber_tallies;
  std::vector<grpc::Status> subscriber_status;
  StreamTally producer_tally;
  grpc::Status producer_status;
  int pending = 0;  // calls not yet done
  bool producer_done = false;
  bool mesh = false;  // asked for the mesh output
};

std::int64_t since_epoch_us(Clock::time_point time) {
  return std::chrono::duration_cast<std::chrono::microseconds>(time.time_since_epoch()).count();
}

/// Whether every frame of `batch` carries the header's V × 3 coordinates in the header's encoding.
bool carries_positions(const client::v1::FrameBatch& batch, const StreamTally& tally) {
  const auto expected = static_cast<std::size_t>(batch.t_us_size()) * tally.mesh_coordinates;
  if (tally.mesh_coordinates == 0) return false;
  if (tally.mesh_int16) return batch.mesh_positions_int16().size() == expected * 2 && batch.mesh_positions().empty();
  return static_cast<std::size_t>(batch.mesh_positions_size()) == expected && batch.mesh_positions_int16().empty();
}

void count_frames(const client::v1::TrackMessage& message, const Run& run, StreamTally& tally, bool verify) {
  if (message.has_header() && message.header().has_mesh()) {
    tally.mesh_coordinates = std::size_t{message.header().mesh().vertex_count()} * 3;
    tally.mesh_int16 = message.header().mesh().encoding() == client::v1::MESH_ENCODING_INT16;
  }
  if (!message.has_frames()) return;
  const std::int64_t arrival_us = since_epoch_us(Clock::now());
  const auto& batch = message.frames();
  ++tally.batches;
  if (verify && run.mesh && !carries_positions(batch, tally)) {
    tally.without_positions += static_cast<std::uint64_t>(batch.t_us_size());
  }
  if (!verify) {
    const std::int64_t sent = run.last_sent_us.load(std::memory_order_acquire);
    const auto latency = static_cast<std::int32_t>(std::clamp<std::int64_t>(arrival_us - sent, 0, INT32_MAX));
    tally.frames += static_cast<std::uint64_t>(batch.t_us_size());
    tally.latencies_us.insert(tally.latencies_us.end(), static_cast<std::size_t>(batch.t_us_size()), latency);
    return;
  }
  const Utterance& utterance = *run.utterance;
  const auto count = static_cast<std::size_t>(batch.t_us_size());
  const std::uint64_t first = batch.first_frame();
  tally.frames += count;
  if (count == 0) return;
  const std::size_t channels = utterance.frame_values.size() / std::max<std::size_t>(1, utterance.frame_t_us.size());
  const bool in_range = first < utterance.frame_t_us.size() && count <= utterance.frame_t_us.size() - first;
  const bool same =
      in_range && static_cast<std::size_t>(batch.values_size()) == count * channels &&
      std::memcmp(batch.t_us().data(), utterance.frame_t_us.data() + first, count * sizeof(std::int64_t)) == 0 &&
      std::memcmp(batch.values().data(), utterance.frame_values.data() + first * channels,
                  count * channels * sizeof(float)) == 0;
  if (!same) {
    tally.unexpected += count;
    return;
  }
  const std::int64_t sent = run.sent_us[utterance.released_by[first]].load(std::memory_order_acquire);
  const auto latency = static_cast<std::int32_t>(std::clamp<std::int64_t>(arrival_us - sent, 0, INT32_MAX));
  tally.latencies_us.insert(tally.latencies_us.end(), count, latency);
}

/// Whether producer `p` asks for the mesh: round((p+1)·share) > round(p·share),
/// so round(N·share) of N producers do, spread evenly.
bool producer_has_mesh(int p, double share) {
  const auto mesh_before = [share](int n) { return std::floor(static_cast<double>(n) * share + 0.5); };
  return mesh_before(p + 1) > mesh_before(p);
}

class LoadTest {
 public:
  LoadTest(const LoadTestConfig& config, asio::io_context& io, LoadClient& client, const std::vector<Utterance>& pool)
      : config_(config), io_(io), client_(client), pool_(pool), work_(asio::make_work_guard(io_)), stop_timer_(io_) {}

  Results run() {
    start_ = Clock::now();
    end_ = start_ + config_.duration;
    const auto stagger = std::min<Clock::duration>(std::chrono::seconds(1), config_.duration / 10);
    for (int p = 0; p < config_.producers; ++p) {
      producers_.push_back(std::make_unique<Producer>(io_));
      Producer& producer = *producers_.back();
      producer.index = p;
      producer.mesh = producer_has_mesh(p, config_.mesh.share);
      ++totals_.by_mesh[producer.mesh].producers;
      producer.timer.expires_at(start_ + stagger * p / config_.producers);
      producer.timer.async_wait([this, &producer](const boost::system::error_code& error) {
        if (!error) start_utterance(producer);
      });
    }
    active_ = config_.producers;
    stop_timer_.expires_at(end_ + kGrace);
    stop_timer_.async_wait([this](const boost::system::error_code& error) {
      if (error) return;
      stopping_ = true;
      for (auto& producer : producers_) {
        if (producer->run && producer->run->call) producer->run->call->cancel();
        if (producer->run) {
          for (auto& subscriber : producer->run->subscribers) subscriber->cancel();
        }
      }
    });
    io_.run();
    return std::move(totals_);
  }

  std::chrono::duration<double> elapsed() const { return finished_at_ - start_; }

 private:
  struct Producer {
    explicit Producer(asio::io_context& io) : timer(io) {}
    int index = 0;
    bool mesh = false;
    std::uint64_t runs = 0;
    asio::steady_timer timer;
    std::unique_ptr<Run> run;
  };

  void start_utterance(Producer& producer) {
    if (stopping_ || Clock::now() >= end_) {
      if (--active_ == 0) {
        finished_at_ = Clock::now();
        stop_timer_.cancel();
        client_.close();
        work_.reset();
      }
      return;
    }
    const std::size_t which = (static_cast<std::size_t>(producer.index) * 7 + producer.runs) % pool_.size();
    auto run = std::make_unique<Run>();
    run->utterance = &pool_[which];
    const std::size_t slots = run->utterance->requests.phonemes.size() + 1;
    run->sent_us = std::make_unique<std::atomic<std::int64_t>[]>(slots);
    for (std::size_t i = 0; i < slots; ++i) run->sent_us[i].store(0);
    run->pending = 1;
    run->mesh = producer.mesh;
    ++totals_.by_mesh[producer.mesh].utterances_started;

    client::v1::AnimationSettings settings;
    settings.set_phone_set("arpabet");
    settings.mutable_outputs()->set_channels(true);
    if (producer.mesh) {
      client::v1::MeshOutput& mesh = *settings.mutable_outputs()->mutable_mesh();
      mesh.set_enabled(true);
      mesh.set_subdivision(config_.mesh.subdivision);
      mesh.set_encoding(config_.mesh.encoding);
      mesh.set_solve(config_.mesh.solve);
    }
    const std::string session = config_.subscribers > 0
                                    ? "loadtest-" + std::to_string(::getpid()) + "-" + std::to_string(producer.index) +
                                          "-" + std::to_string(producer.runs)
                                    : std::string();
    settings.set_session(session);
    ++producer.runs;
    Run* raw = run.get();
    producer.run = std::move(run);
    const std::size_t connection = static_cast<std::size_t>(producer.index) % client_.connections();
    raw->start = Clock::now();
    raw->call = client_.animate(
        connection, settings, raw->utterance->requests,
        [this, raw, &producer, session, connection](const client::v1::TrackMessage& message) {
          count_frames(message, *raw, raw->producer_tally, config_.verify);
          if (message.has_header() && config_.subscribers > 0) {
            asio::post(io_, [this, raw, &producer, session, connection] {
              start_subscribers(producer, *raw, session, connection);
            });
          }
        },
        [this, raw, &producer](const grpc::Status& status) {
          asio::post(io_, [this, raw, &producer, status] {
            raw->producer_status = status;
            raw->producer_done = true;
            call_done(producer, *raw);
          });
        });
    send_due(producer, *raw);
  }

  void start_subscribers(Producer& producer, Run& run, const std::string& session, std::size_t connection) {
    if (stopping_ || run.producer_done || !run.subscribers.empty()) return;
    for (int s = 0; s < config_.subscribers; ++s) {
      run.subscriber_tallies.push_back(std::make_unique<StreamTally>());
      run.subscriber_status.emplace_back();
      StreamTally* tally = run.subscriber_tallies.back().get();
      const std::size_t slot = run.subscriber_status.size() - 1;
      ++run.pending;
      ++totals_.by_mesh[run.mesh].subscriptions;
      Run* raw = &run;
      run.subscribers.push_back(client_.subscribe(
          connection, session,
          [this, raw, tally](const client::v1::TrackMessage& message) {
            count_frames(message, *raw, *tally, config_.verify);
          },
          [this, raw, &producer, slot](const grpc::Status& status) {
            asio::post(io_, [this, raw, &producer, slot, status] {
              raw->subscriber_status[slot] = status;
              call_done(producer, *raw);
            });
          }));
    }
  }

  /// Sends every phoneme whose time has come, then waits for the next one.
  void send_due(Producer& producer, Run& run) {
    if (run.producer_done || run.pending == 0) return;
    const auto& phonemes = run.utterance->requests.phonemes;
    while (run.next_phoneme <= phonemes.size()) {
      const std::size_t i = run.next_phoneme;
      const std::int64_t due_us = i < phonemes.size() ? phonemes[i].start_us() : phonemes.back().end_us();
      const auto due = run.start + std::chrono::microseconds(due_us);
      if (config_.realtime && due > Clock::now()) {
        producer.timer.expires_at(on_send_grid(due));
        producer.timer.async_wait([this, &producer, &run](const boost::system::error_code& error) {
          if (!error) send_due(producer, run);
        });
        return;
      }
      const std::int64_t now_us = since_epoch_us(Clock::now());
      run.sent_us[i].store(now_us, std::memory_order_release);
      run.last_sent_us.store(now_us, std::memory_order_release);
      ++run.next_phoneme;
      if (i == phonemes.size()) {
        run.call->end();
      } else if (!run.call->send_phoneme(i)) {
        return;  // the stream has ended; call_done reports why
      }
    }
  }

  /// `due` rounded up to the next step of a grid shared by all producers (kSendGrid): the
  /// phonemes due within one step are sent together, after one wake-up of the generator's thread.
  Clock::time_point on_send_grid(Clock::time_point due) const {
    const auto steps = (due - start_ + kSendGrid - Clock::duration(1)) / kSendGrid;
    return start_ + steps * kSendGrid;
  }

  void call_done(Producer& producer, Run& run) {
    if (--run.pending > 0) return;
    producer.timer.cancel();
    const Utterance& utterance = *run.utterance;
    const auto expected = utterance.frame_t_us.size();
    Totals& totals = totals_.by_mesh[run.mesh];
    const auto tally = [&](const StreamTally& stream, const grpc::Status& status, std::vector<std::int32_t>& sink) {
      totals.unexpected_frames += stream.unexpected;
      totals.frames_without_positions += stream.without_positions;
      sink.insert(sink.end(), stream.latencies_us.begin(), stream.latencies_us.end());
      if (!status.ok()) {
        ++totals_.errors[std::string(client::status_code_name(status.error_code()))];
        return false;
      }
      if (!config_.verify) return true;
      const std::uint64_t good = stream.frames - stream.unexpected;
      if (good < expected) totals.missing_frames += expected - good;
      return good == expected && stream.unexpected == 0 && stream.without_positions == 0;
    };
    totals.producer_frames += run.producer_tally.frames;
    totals.producer_batches += run.producer_tally.batches;
    if (tally(run.producer_tally, run.producer_status, totals.producer_latencies_us)) ++totals.utterances_complete;
    for (std::size_t s = 0; s < run.subscribers.size(); ++s) {
      totals.subscriber_frames += run.subscriber_tallies[s]->frames;
      totals.subscriber_batches += run.subscriber_tallies[s]->batches;
      if (tally(*run.subscriber_tallies[s], run.subscriber_status[s], totals.subscriber_latencies_us)) {
        ++totals.subscriptions_complete;
      }
    }
    // Destroying the calls here is safe: each has posted its last act. After an
    // error the producer pauses, so that a refusing server is not hammered.
    const bool failed =
        !run.producer_status.ok() || std::any_of(run.subscriber_status.begin(), run.subscriber_status.end(),
                                                 [](const grpc::Status& status) { return !status.ok(); });
    asio::post(io_, [this, &producer, failed] {
      producer.run.reset();
      if (!failed) {
        start_utterance(producer);
        return;
      }
      producer.timer.expires_after(kPauseAfterError);
      producer.timer.async_wait([this, &producer](const boost::system::error_code& error) {
        if (!error) start_utterance(producer);
      });
    });
  }

  const LoadTestConfig& config_;
  asio::io_context& io_;
  LoadClient& client_;
  const std::vector<Utterance>& pool_;
  asio::executor_work_guard<asio::io_context::executor_type> work_;
  asio::steady_timer stop_timer_;
  std::vector<std::unique_ptr<Producer>> producers_;
  Clock::time_point start_;
  Clock::time_point end_;
  Clock::time_point finished_at_;
  int active_ = 0;
  bool stopping_ = false;
  Results totals_;
};

/// What the command line asked for, checked: the run's shape and where and how to connect.
struct Request {
  LoadTestConfig config;
  std::string address;
  LoadClientKind client_kind = LoadClientKind::h2;
  std::string client_name;
  client::ClientOptions client_options;
  int connections = 4;
};

Request parse_request(const Arguments& arguments) {
  if (!arguments.positional().empty()) {
    throw UsageError("loadtest takes no arguments, got '" + arguments.positional().front() + "'");
  }
  Request request;
  request.address = loopback_server_address(arguments);
  if (arguments.flag("realtime") && arguments.flag("fast")) throw UsageError("choose one of --realtime and --fast");
  LoadTestConfig& config = request.config;
  config.producers = parse_int_option("producers", arguments.value("producers").value_or("10"), 1, 10'000);
  config.subscribers =
      parse_int_option("subscribers-per-session", arguments.value("subscribers-per-session").value_or("0"), 0, 16);
  config.duration =
      std::chrono::seconds(parse_int_option("duration", arguments.value("duration").value_or("10"), 1, 600));
  config.realtime = !arguments.flag("fast");
  config.phonemes = static_cast<std::size_t>(
      parse_int_option("phonemes-per-utterance", arguments.value("phonemes-per-utterance").value_or("30"), 1, 10'000));
  config.seed =
      static_cast<std::uint64_t>(parse_int_option("seed", arguments.value("seed").value_or("1"), 0, INT32_MAX));
  config.verify = !arguments.flag("no-verify");
  request.connections = parse_int_option("connections", arguments.value("connections").value_or("4"), 1, 64);
  request.client_options = connection_options(arguments);
  const bool tls = request.client_options.tls.on();
  request.client_name = arguments.value("client").value_or(tls ? "grpc" : "h2");
  if (request.client_name != "h2" && request.client_name != "grpc") {
    throw UsageError("--client: unknown client '" + request.client_name + "' (choose h2 or grpc)");
  }
  request.client_kind = request.client_name == "h2" ? LoadClientKind::h2 : LoadClientKind::grpc;
  if (request.client_kind == LoadClientKind::h2 && tls) {
    throw UsageError("--client h2 speaks plaintext HTTP/2 only; with --tls, --ca, --cert or --key use --client grpc");
  }
  config.mesh.share = parse_double_option("mesh-share", arguments.value("mesh-share").value_or("0"));
  if (config.mesh.share < 0.0 || config.mesh.share > 1.0) {
    throw UsageError(
        out_of_range_text("--mesh-share", *arguments.value("mesh-share"), "a fraction of the producers, 0 to 1"));
  }
  config.mesh.subdivision = static_cast<std::uint32_t>(parse_render_plan(arguments).mesh_subdivision);
  const std::string encoding = arguments.value("mesh-encoding").value_or("float32");
  if (encoding == "float32") {
    config.mesh.encoding = client::v1::MESH_ENCODING_FLOAT32;
  } else if (encoding == "int16") {
    config.mesh.encoding = client::v1::MESH_ENCODING_INT16;
  } else {
    throw UsageError("--mesh-encoding: unknown encoding '" + encoding + "' (choose float32 or int16)");
  }
  config.mesh.solve = parse_fast_mesh_solve_option(arguments.value("mesh-solve").value_or("full"))
                          ? client::v1::MESH_SOLVE_FAST
                          : client::v1::MESH_SOLVE_FULL;
  const bool mesh_options =
      arguments.value("mesh-subdivision") || arguments.value("mesh-encoding") || arguments.value("mesh-solve");
  if (mesh_options && config.mesh.share == 0.0) {
    throw UsageError("--mesh-subdivision, --mesh-encoding and --mesh-solve need --mesh-share above 0");
  }
  return request;
}

/// The utterances the producers take turns with, rendered offline once.
std::vector<Utterance> make_pool(const LoadTestConfig& config) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const std::optional<PhoneSet> arpabet = PhoneSet::builtin("arpabet", model);
  if (!arpabet) throw std::logic_error("the built-in ARPAbet phone set is missing");
  std::vector<Utterance> pool;
  const std::size_t pool_size = std::min<std::size_t>(kUtterancePool, static_cast<std::size_t>(config.producers) * 4);
  for (std::size_t i = 0; i < pool_size; ++i) {
    pool.push_back(make_utterance(config.seed * 1'000'003 + i, config.phonemes, model, *arpabet));
  }
  return pool;
}

}  // namespace

int run_loadtest(std::span<const std::string_view> args) {
  const Arguments arguments = Arguments::parse(args, kOptions, "loadtest");
  if (print_help_if_asked(arguments, kUsage, kDescription, kOptions, std::cout)) return 0;
  if (arguments.flag("listen")) return run_listen_load(arguments);
  for (const char* option : {"transcript", "latency-ms"}) {
    if (arguments.value(option) || arguments.flag(option))
      throw UsageError(std::string("--") + option + ": needs --listen");
  }
  Request request = parse_request(arguments);
  // As lipsyncd does (server/src/main.cpp): Debian's abseil leaves the deadlock detection of
  // gRPC's Mutexes on, a cost per lock that the generator should not spend on every message.
  absl::SetMutexDeadlockDetectionMode(absl::OnDeadlockCycle::kIgnore);
  const std::vector<Utterance> pool = make_pool(request.config);

  request.client_options.stream_timeout = request.config.duration + kGrace + std::chrono::seconds(5);
  asio::io_context io;
  const std::unique_ptr<LoadClient> client =
      connect_load_client(request.client_kind, io, request.address, request.client_options, request.connections);

  LoadTest test(request.config, io, *client, pool);
  const double cpu_before = process_cpu_seconds();
  Results results = test.run();
  const double seconds = test.elapsed().count();
  const Summary summary = summarise(std::move(results), seconds, (process_cpu_seconds() - cpu_before) / seconds);
  if (arguments.flag("json")) {
    write_json_report(request.config, request.address, request.client_name, summary, std::cout);
  } else {
    write_text_report(request.config, request.client_name, summary, std::cout);
  }
  return summary.every_frame ? 0 : kExitInputError;
}

}  // namespace lipsync::cli
