// libFuzzer target: the Animate stream of the real LipSync service, in process.
// The bytes are a program of client actions (animate_program.hpp): open up to
// two Animate streams (with or without x-lipsync-session metadata), send
// settings, phoneme chunks, `end` or raw message bytes, half-close, cancel, and
// open or cancel up to two Subscribe streams. They run against one
// LipSyncService built once per process behind a gRPC server with no port,
// reached through its in-process channel (real gRPC calls, reactors, outboxes
// and sessions; no sockets, no listener).
//
// Contract, checked on every call of every input:
// - it ends within 5 s (every call has that deadline) with a status the API
//   documents for it: Animate OK, INVALID_ARGUMENT, RESOURCE_EXHAUSTED,
//   ALREADY_EXISTS (DEADLINE_EXCEEDED from a late face, mesh streams only);
//   Subscribe OK, NOT_FOUND, ABORTED, RESOURCE_EXHAUSTED, INVALID_ARGUMENT;
//   CANCELLED only for a call the client cancelled; a refusal's message is
//   non-empty and short (echoed values are excerpts);
// - what it received is a header first, then frame batches numbered without
//   gaps whose times strictly increase, with every output's values for every
//   frame, then at most one summary counting the frames; an OK call has both;
// - an Animate stream that ended OK at the exact lookahead sent the frames
//   Render gives for the same settings and phonemes, bit for bit;
// - afterwards the server holds nothing: no stream counted as open, no session
//   (ended sessions are retained for 0 ms here), no mesh capacity in use, and
//   a small Animate call still works.
// What a run costs is bounded by the fuzzer, not the server: a mesh stream is
// rare (the settings must ask for it) and is kept to subdivision 0, 30 fps and
// 100 phonemes ending within 5 s; messages that would exceed that are not sent.
// The server is never destroyed: gRPC's global state outlives it otherwise,
// and LeakSanitizer sees it as reachable.
#include <google/protobuf/stubs/logging.h>
#include <grpcpp/grpcpp.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "animate_program.hpp"
#include "catalog.hpp"
#include "fuzz_support.hpp"
#include "lipsync/server/config.hpp"
#include "lipsync/v1/lipsync.pb.h"
#include "rpc/plan.hpp"
#include "rpc/service.hpp"

namespace {

using lipsync::fuzz::check;
using lipsync::fuzz::Metadata;
using lipsync::fuzz::Op;
using lipsync::fuzz::ProgramReader;
namespace v1 = lipsync::v1;
using Clock = std::chrono::steady_clock;

constexpr auto kCallDeadline = std::chrono::seconds(5);
/// Longest status message accepted: a few excerpts (64 bytes each) and their words.
constexpr std::size_t kMaxStatusMessageBytes = 1024;
/// The fuzzer's bound on a mesh stream (see the top of the file).
constexpr std::int64_t kMeshUtteranceUs = 5'000'000;
constexpr int kMeshPhonemes = 100;
constexpr std::uint32_t kMeshFps = 30;
/// The lookahead at which an Animate stream equals Render bit for bit.
constexpr std::uint32_t kExactLookahead = 7;

/// The server's defaults, with limits small enough for the fuzzer to reach
/// every refusal: two streams of a kind and one session at a time, 1,000
/// phonemes and a minute of speech per utterance, and ended sessions forgotten
/// at once (so that a leaked one shows after every input).
lipsync::server::ServerConfig fuzz_config() {
  lipsync::server::ServerConfig config;
  config.listen = "in-process";
  config.log_level = "off";
  config.max_streams = 3;
  config.max_sessions = 1;
  config.max_subscribers_per_session = 1;
  config.max_phonemes = 1'000;
  config.max_utterance_ms = 60'000;
  config.subscriber_queue_frames = 256;
  config.stalled_subscriber_ms = 1'000;
  config.session_retention_ms = 0;
  config.face_threads = 1;
  config.face_priority = "normal";  // idle threads could starve on a busy machine: a hang that is not the server's
  return config;
}

/// LipSyncService behind a gRPC server without a port, and a channel to it.
struct InProcessServer {
  explicit InProcessServer(lipsync::server::ServerConfig config_in)
      : config(std::move(config_in)), catalog(config.models), service(config, catalog) {
    grpc::ServerBuilder builder;
    builder.SetMaxReceiveMessageSize(static_cast<int>(config.max_message_bytes));
    builder.RegisterService(&service);
    server = builder.BuildAndStart();
    check(server != nullptr, "the in-process server starts");
    grpc::ChannelArguments arguments;
    arguments.SetMaxReceiveMessageSize(-1);
    channel = server->InProcessChannel(arguments);
  }

  lipsync::server::ServerConfig config;
  lipsync::server::ModelCatalog catalog;
  lipsync::server::LipSyncService service;
  std::unique_ptr<grpc::Server> server;
  std::shared_ptr<grpc::Channel> channel;
};

InProcessServer& in_process_server() {
  static InProcessServer* const server = new InProcessServer(fuzz_config());  // kept for the process (see top)
  return *server;
}

const grpc::internal::RpcMethod kAnimateMethod("/lipsync.v1.LipSync/Animate",
                                               grpc::internal::RpcMethod::BIDI_STREAMING);
const grpc::internal::RpcMethod kSubscribeMethod("/lipsync.v1.LipSync/Subscribe",
                                                 grpc::internal::RpcMethod::SERVER_STREAMING);

grpc::ByteBuffer byte_buffer(const std::string& bytes) {
  grpc::Slice slice(bytes);
  return grpc::ByteBuffer(&slice, 1);
}

std::string bytes_of(const grpc::ByteBuffer& buffer) {
  std::vector<grpc::Slice> slices;
  check(buffer.Dump(&slices).ok(), "a received message can be read");
  std::string bytes;
  for (const grpc::Slice& slice : slices) bytes.append(reinterpret_cast<const char*>(slice.begin()), slice.size());
  return bytes;
}

/// How one call ended and what it received, in the order received.
struct CallOutcome {
  std::vector<std::string> messages;
  grpc::Status status;
  bool cancelled_by_client = false;
  Clock::duration took{};
};

/// A raw-bytes client call with a reader thread that takes every message as it comes
/// (so the server's outbox always drains and the client's writes never wait on it).
template <class Stream>
class RawCall {
 public:
  explicit RawCall(const std::optional<std::string>& metadata) {
    context_.set_deadline(std::chrono::system_clock::now() + kCallDeadline);
    if (metadata) context_.AddMetadata(lipsync::server::SessionRouting::kMetadataKey, *metadata);
  }
  RawCall(const RawCall&) = delete;
  RawCall& operator=(const RawCall&) = delete;

  void cancel() {
    outcome_.cancelled_by_client = true;
    context_.TryCancel();
  }

 protected:
  void start_reading(Stream* stream) {
    stream_.reset(stream);
    reader_ = std::thread([this] {
      grpc::ByteBuffer buffer;
      while (stream_->Read(&buffer)) outcome_.messages.push_back(bytes_of(buffer));
    });
  }
  CallOutcome finish_reading() {
    reader_.join();
    outcome_.status = stream_->Finish();
    outcome_.took = Clock::now() - started_;
    return std::move(outcome_);
  }

  grpc::ClientContext context_;
  std::unique_ptr<Stream> stream_;

 private:
  const Clock::time_point started_ = Clock::now();
  std::thread reader_;
  CallOutcome outcome_;
};

/// An Animate call, and what the client sent on it that the server could parse.
class AnimateCall : public RawCall<grpc::ClientReaderWriter<grpc::ByteBuffer, grpc::ByteBuffer>> {
 public:
  AnimateCall(grpc::Channel& channel, const std::optional<std::string>& metadata) : RawCall(metadata) {
    start_reading(grpc::internal::ClientReaderWriterFactory<grpc::ByteBuffer, grpc::ByteBuffer>::Create(
        &channel, kAnimateMethod, &context_));
  }

  /// Sends `request` unless the fuzzer's bound on mesh streams forbids it.
  void send(const v1::AnimateRequest& request) {
    if (!within_mesh_bound(request)) return;
    write(request.SerializeAsString(), request);
  }
  /// Sends `bytes` as they are (when they parse as an AnimateRequest, under the same bound).
  void send_raw(const std::string& bytes) {
    v1::AnimateRequest request;
    if (request.ParseFromString(bytes)) {
      if (!within_mesh_bound(request)) return;
      write(bytes, request);
    } else {
      write(bytes, std::nullopt);
    }
  }
  void half_close() {
    if (half_closed_) return;
    half_closed_ = true;
    stream_->WritesDone();
  }
  CallOutcome finish() {
    half_close();
    return finish_reading();
  }

  bool mesh() const { return mesh_; }
  /// The messages sent, in order, if every one parsed (what Render is compared with).
  const std::optional<std::vector<v1::AnimateRequest>>& sent() const { return sent_; }

 private:
  bool within_mesh_bound(const v1::AnimateRequest& request) const {
    if (request.has_settings() && lipsync::server::wants_mesh(request.settings())) {
      const auto& settings = request.settings();
      if (!settings.outputs().mesh().has_subdivision() || settings.outputs().mesh().subdivision() != 0 ||
          settings.fps() > kMeshFps) {
        return false;
      }
    }
    if (!mesh_ || !request.has_phonemes()) return true;
    if (mesh_phonemes_ + request.phonemes().phonemes_size() > kMeshPhonemes) return false;
    return std::all_of(request.phonemes().phonemes().begin(), request.phonemes().phonemes().end(),
                       [](const v1::Phoneme& phoneme) { return phoneme.end_us() <= kMeshUtteranceUs; });
  }

  void write(const std::string& bytes, const std::optional<v1::AnimateRequest>& request) {
    if (half_closed_ || broken_) return;
    if (sent_ && request) {
      sent_->push_back(*request);
    } else {
      sent_.reset();
    }
    // Only the first message may be settings: the server refuses the rest.
    if (request && request->has_settings() && !first_sent_) mesh_ = lipsync::server::wants_mesh(request->settings());
    if (request && request->has_phonemes() && mesh_) mesh_phonemes_ += request->phonemes().phonemes_size();
    first_sent_ = true;
    broken_ = !stream_->Write(byte_buffer(bytes));
  }

  bool half_closed_ = false;
  bool broken_ = false;  // a write failed: the call is over
  bool first_sent_ = false;
  bool mesh_ = false;
  int mesh_phonemes_ = 0;
  std::optional<std::vector<v1::AnimateRequest>> sent_{std::in_place};
};

class SubscribeCall : public RawCall<grpc::ClientReader<grpc::ByteBuffer>> {
 public:
  SubscribeCall(grpc::Channel& channel, const v1::SubscribeRequest& request, const std::optional<std::string>& metadata)
      : RawCall(metadata) {
    start_reading(grpc::internal::ClientReaderFactory<grpc::ByteBuffer>::Create(
        &channel, kSubscribeMethod, &context_, byte_buffer(request.SerializeAsString())));
  }
  CallOutcome finish() { return finish_reading(); }
};

// --- decoding the program ---------------------------------------------------------

std::optional<std::string> read_metadata(ProgramReader& program, const std::string& body_session) {
  std::string value;
  switch (static_cast<Metadata>(program.u8() % 3)) {
    case Metadata::none:
      return std::nullopt;
    case Metadata::same_as_body:
      value = body_session;
      break;
    case Metadata::explicit_value:
      value = program.string();
      break;
  }
  // gRPC's client refuses (asserts on) metadata values that are not printable ASCII: no
  // client can send them, so they are mapped into that range (a printable name stays as it is).
  for (char& c : value) {
    const unsigned byte = static_cast<unsigned char>(c);
    c = static_cast<char>(byte >= 0x20 && byte < 0x7F ? byte : 0x20 + byte % 0x5F);
  }
  return value;
}

v1::AnimateRequest read_settings(ProgramReader& program) {
  using namespace lipsync::fuzz;
  const std::uint16_t bits = program.u16();
  v1::AnimateRequest request;
  v1::AnimationSettings& settings = *request.mutable_settings();
  if (bits & kModel) settings.set_model(program.string());
  if (bits & kFps) settings.set_fps(program.u16());
  if (bits & kPhoneSet) settings.set_phone_set(program.string());
  if (bits & kLookahead) settings.set_lookahead(program.u8());
  if (bits & kFixedRate) settings.set_fixed_rate(true);
  if (bits & kClosureFraction) settings.set_closure_fraction(program.f64());
  if (bits & kSession) settings.set_session(program.string());
  if (bits & kMediaClock) {
    settings.mutable_media_clock()->set_clock(program.string());
    settings.mutable_media_clock()->set_utterance_zero_us(program.i64());
  }
  v1::OutputSelection& outputs = *settings.mutable_outputs();
  if (bits & kChannels) outputs.set_channels(true);
  if (bits & kArkit) outputs.set_arkit(true);
  if (bits & kVisemes) {
    outputs.mutable_visemes()->set_enabled(true);
    outputs.mutable_visemes()->set_vocabulary(static_cast<v1::VisemeVocabulary>(program.u8()));
  }
  if (bits & kRhubarbShapes) outputs.mutable_visemes()->set_rhubarb_extended_shapes(program.string());
  if (bits & kMesh) {
    outputs.mutable_mesh()->set_enabled(true);
    outputs.mutable_mesh()->set_subdivision(program.u8());
    outputs.mutable_mesh()->set_encoding(static_cast<v1::MeshEncoding>(program.u8()));
  }
  return request;
}

v1::AnimateRequest read_phonemes(ProgramReader& program, std::int64_t& end_us) {
  v1::AnimateRequest request;
  v1::PhonemeChunk& chunk = *request.mutable_phonemes();
  for (int count = program.u8(); count > 0; --count) {
    v1::Phoneme& phoneme = *chunk.add_phonemes();
    phoneme.set_label(program.string());
    if (program.u8() % 2 == 0) {
      // Unsigned, so that a huge gap wraps instead of overflowing (C++20 converts modulo 2^64).
      const std::uint64_t start_us = static_cast<std::uint64_t>(end_us) + program.varint();
      phoneme.set_start_us(static_cast<std::int64_t>(start_us));
      phoneme.set_end_us(static_cast<std::int64_t>(start_us + program.varint()));
    } else {
      phoneme.set_start_us(program.i64());
      phoneme.set_end_us(program.i64());
    }
    end_us = phoneme.end_us();
  }
  return request;
}

// --- the contract -------------------------------------------------------------------

void check_status(const CallOutcome& outcome, std::initializer_list<grpc::StatusCode> documented, bool mesh) {
  const grpc::Status& status = outcome.status;
  check(outcome.took < kCallDeadline || status.error_code() != grpc::StatusCode::DEADLINE_EXCEEDED,
        "a call ends within its 5 s deadline");
  if (status.ok()) return;
  const bool is_documented = std::find(documented.begin(), documented.end(), status.error_code()) != documented.end();
  const bool cancelled = outcome.cancelled_by_client && status.error_code() == grpc::StatusCode::CANCELLED;
  const bool late_face = mesh && status.error_code() == grpc::StatusCode::DEADLINE_EXCEEDED;
  if (!is_documented && !cancelled && !late_face) {
    std::fprintf(stderr, "status %d: %.300s\n", status.error_code(), status.error_message().c_str());
    check(false, "a call ends with a status its method documents");
  }
  check(!status.error_message().empty(), "a refusal says why");
  check(status.error_message().size() <= kMaxStatusMessageBytes, "a refusal's message is short (values as excerpts)");
}

/// The frames of a call, as one track.
struct ReceivedTrack {
  std::optional<v1::TrackHeader> header;
  std::optional<v1::TrackSummary> summary;
  v1::FrameBatch frames;  // every batch's fields appended
};

void append(const v1::FrameBatch& batch, v1::FrameBatch& all) {
  all.mutable_t_us()->MergeFrom(batch.t_us());
  all.mutable_kinds()->MergeFrom(batch.kinds());
  all.mutable_values()->MergeFrom(batch.values());
  all.mutable_arkit()->MergeFrom(batch.arkit());
  all.mutable_viseme_weights()->MergeFrom(batch.viseme_weights());
  all.mutable_viseme_events()->MergeFrom(batch.viseme_events());
}

/// A header, frame batches numbered without gaps (a subscriber may join after
/// frame 0) with strictly increasing times and every selected output per frame,
/// then at most one summary that counts the frames.
ReceivedTrack check_track(const CallOutcome& outcome, bool from_frame_zero) {
  ReceivedTrack track;
  std::optional<std::uint64_t> next_frame;
  if (from_frame_zero) next_frame = 0;
  std::int64_t previous_t_us = std::numeric_limits<std::int64_t>::min();
  for (const std::string& bytes : outcome.messages) {
    v1::TrackMessage message;
    check(message.ParseFromString(bytes), "every message is a TrackMessage");
    check(!track.summary, "nothing follows the summary");
    if (message.has_header()) {
      check(!track.header, "one header");
      track.header = message.header();
      continue;
    }
    check(track.header.has_value(), "the header comes first");
    if (message.has_summary()) {
      track.summary = message.summary();
      check(!next_frame || track.summary->frames() == *next_frame, "the summary counts the frames sent");
      continue;
    }
    check(message.has_frames(), "a message is a header, frames or a summary");
    const v1::FrameBatch& batch = message.frames();
    const auto frames = static_cast<std::size_t>(batch.t_us_size());
    check(frames > 0, "a batch has frames");
    check(!next_frame || batch.first_frame() == *next_frame, "batches are numbered without gaps");
    next_frame = batch.first_frame() + frames;
    for (const std::int64_t t_us : batch.t_us()) {
      check(t_us > previous_t_us, "frame times strictly increase");
      previous_t_us = t_us;
    }
    const v1::TrackHeader& header = *track.header;
    check(static_cast<std::size_t>(batch.kinds_size()) == frames, "a kind per frame");
    check(static_cast<std::size_t>(batch.values_size()) == frames * static_cast<std::size_t>(header.channels_size()),
          "the channels of every frame");
    check(static_cast<std::size_t>(batch.arkit_size()) == frames * static_cast<std::size_t>(header.arkit_names_size()),
          "the ARKit weights of every frame");
    check(static_cast<std::size_t>(batch.viseme_weights_size()) ==
              frames * static_cast<std::size_t>(header.viseme_names_size()),
          "the viseme weights of every frame");
    if (header.has_mesh()) {
      const std::size_t coordinates = frames * header.mesh().vertex_count() * 3;
      check(static_cast<std::size_t>(batch.mesh_positions_size()) == coordinates ||
                batch.mesh_positions_int16().size() == coordinates * 2,
            "the mesh of every frame");
    }
    append(batch, track.frames);
  }
  if (outcome.status.ok()) check(track.header && track.summary, "an OK call has a header and a summary");
  return track;
}

/// Animate = Render: the frames of an Animate stream that ended OK at the exact
/// lookahead equal a Render of its settings and phonemes.
/// The same values bit for bit (NaN included), the same count.
template <class Field>
bool same_bits(const Field& a, const Field& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), sizeof(*a.data()) * a.size()) == 0);
}

void check_equals_render(const std::vector<v1::AnimateRequest>& sent, const ReceivedTrack& animated) {
  v1::RenderRequest request;
  // The utterance is the first message's settings and the phonemes up to `end`. What follows
  // `end` is refused, or, if gRPC cannot decode it, ends the reads as a half-close does (OK).
  for (const v1::AnimateRequest& message : sent) {
    if (message.has_end()) break;
    if (&message == &sent.front()) *request.mutable_settings() = message.settings();
    for (const v1::Phoneme& phoneme : message.phonemes().phonemes()) *request.add_phonemes() = phoneme;
  }
  if (request.settings().has_lookahead() && request.settings().lookahead() != kExactLookahead) return;
  // Chunks add up to more than one message may carry (long labels the phone set ignores).
  if (request.ByteSizeLong() > in_process_server().config.max_message_bytes) return;
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + kCallDeadline);
  v1::RenderResponse response;
  const grpc::Status status = v1::LipSync::NewStub(in_process_server().channel)->Render(&context, request, &response);
  if (!status.ok())
    std::fprintf(stderr, "Render: status %d: %.300s\n", status.error_code(), status.error_message().c_str());
  check(status.ok(), "what Animate accepted, Render accepts");
  const v1::FrameBatch& rendered = response.frames();
  check(same_bits(rendered.t_us(), animated.frames.t_us()), "Animate's frame times are Render's");
  check(same_bits(rendered.kinds(), animated.frames.kinds()), "Animate's frame kinds are Render's");
  check(same_bits(rendered.values(), animated.frames.values()), "Animate's channel values are Render's, bit for bit");
  check(same_bits(rendered.arkit(), animated.frames.arkit()), "Animate's ARKit weights are Render's, bit for bit");
  check(same_bits(rendered.viseme_weights(), animated.frames.viseme_weights()),
        "Animate's viseme weights are Render's, bit for bit");
  check(rendered.viseme_events_size() == animated.frames.viseme_events_size() &&
            std::equal(rendered.viseme_events().begin(), rendered.viseme_events().end(),
                       animated.frames.viseme_events().begin(),
                       [](const v1::VisemeEvent& a, const v1::VisemeEvent& b) {
                         return a.viseme() == b.viseme() && a.start_us() == b.start_us();
                       }),
        "Animate's viseme events are Render's");
  check(response.summary().frames() == animated.summary->frames(), "Animate's frame count is Render's");
}

/// The open-stream gauges of every method and tenant, added up.
std::int64_t open_streams(const lipsync::server::ServerMetrics& metrics) {
  std::int64_t open = 0;
  metrics.open_streams.each(
      [&](const lipsync::server::LabelValues&, const lipsync::server::Level& level) { open += level.value(); });
  return open;
}

/// Nothing of the input's calls is left in the server (their OnDone may come a
/// moment after the client saw the status), and a small Animate call works.
void check_server_is_clean() {
  auto& service = in_process_server().service;
  const auto deadline = Clock::now() + std::chrono::seconds(2);
  const auto clean = [&] {
    return service.admission().calls_in_progress() == 0 && service.admission().active_streams() == 0 &&
           open_streams(service.metrics()) == 0 && service.face_capacity().used_milli() == 0;
  };
  while (!clean() && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::microseconds(100));
  check(service.admission().calls_in_progress() == 0, "no call is still in progress after its client saw the end");
  check(service.admission().active_streams() == 0, "no stream is still counted as open");
  check(open_streams(service.metrics()) == 0, "the open-stream gauges are 0");
  check(service.face_capacity().used_milli() == 0, "no mesh capacity is still held");
  check(service.sessions().size() == 0, "no session outlives its producer (retention is 0 here)");

  AnimateCall probe(*in_process_server().channel, std::nullopt);
  v1::AnimateRequest settings;
  settings.mutable_settings();
  probe.send(settings);
  v1::AnimateRequest phonemes;
  v1::Phoneme& phoneme = *phonemes.mutable_phonemes()->add_phonemes();
  phoneme.set_label("AA");
  phoneme.set_end_us(100'000);
  probe.send(phonemes);
  v1::AnimateRequest end;
  end.mutable_end();
  probe.send(end);
  const CallOutcome outcome = probe.finish();
  check(outcome.status.ok(), "the server still animates after the input");
  check(!check_track(outcome, true).frames.t_us().empty(), "the server still sends frames after the input");
}

}  // namespace

/// Protobuf's log of undecodable UTF-8 strings would drown the fuzzer's own output.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  spdlog::set_level(spdlog::level::off);
  in_process_server();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  InProcessServer& server = in_process_server();
  grpc::Channel& channel = *server.channel;
  std::optional<AnimateCall> producers[2];
  std::optional<SubscribeCall> subscribers[2];
  std::int64_t end_us[2] = {0, 0};  // where a relative phoneme starts counting, per stream
  std::string last_session;         // the body session of the last settings sent, for metadata

  ProgramReader program(lipsync::fuzz::bytes(data, size));
  while (!program.done()) {
    const std::uint8_t action = program.u8();
    const int slot = (action >> 4) & 1;
    const auto op = static_cast<Op>(action & 0x0F);
    std::optional<AnimateCall>& producer = producers[slot];
    const auto opened = [&]() -> AnimateCall& {
      if (!producer) producer.emplace(channel, std::nullopt);
      return *producer;
    };
    switch (op) {
      case Op::open: {
        const std::optional<std::string> metadata = read_metadata(program, last_session);  // read even if unused
        if (!producer) producer.emplace(channel, metadata);
        break;
      }
      case Op::settings: {
        const v1::AnimateRequest request = read_settings(program);
        last_session = request.settings().session();
        opened().send(request);
        break;
      }
      case Op::phonemes:
        opened().send(read_phonemes(program, end_us[slot]));
        break;
      case Op::end: {
        v1::AnimateRequest request;
        request.mutable_end();
        opened().send(request);
        break;
      }
      case Op::raw:
        opened().send_raw(program.string());
        break;
      case Op::half_close:
        if (producer) producer->half_close();
        break;
      case Op::cancel:
        if (producer) producer->cancel();
        break;
      case Op::subscribe: {
        v1::SubscribeRequest request;
        request.set_session(program.string());
        request.set_start(static_cast<v1::SubscribeRequest::Start>(program.u8()));
        const std::optional<std::string> metadata = read_metadata(program, request.session());
        if (!subscribers[slot]) subscribers[slot].emplace(channel, request, metadata);
        break;
      }
      case Op::cancel_subscriber:
        if (subscribers[slot]) subscribers[slot]->cancel();
        break;
      case Op::count:
        break;
    }
  }

  using grpc::StatusCode;
  for (std::optional<AnimateCall>& producer : producers) {
    if (!producer) continue;
    const CallOutcome outcome = producer->finish();
    check_status(outcome, {StatusCode::INVALID_ARGUMENT, StatusCode::RESOURCE_EXHAUSTED, StatusCode::ALREADY_EXISTS},
                 producer->mesh());
    const ReceivedTrack track = check_track(outcome, true);
    if (outcome.status.ok() && producer->sent() && !producer->mesh()) check_equals_render(*producer->sent(), track);
  }
  for (std::optional<SubscribeCall>& subscriber : subscribers) {
    if (!subscriber) continue;
    const CallOutcome outcome = subscriber->finish();
    check_status(
        outcome,
        {StatusCode::NOT_FOUND, StatusCode::ABORTED, StatusCode::RESOURCE_EXHAUSTED, StatusCode::INVALID_ARGUMENT},
        false);
    check_track(outcome, false);
  }
  check_server_is_clean();
  return 0;
}
