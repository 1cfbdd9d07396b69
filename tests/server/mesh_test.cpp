// lipsyncd's mesh output over the network: the topology once in the header,
// per-frame positions equal to FaceSolver run offline on render_track's frames by
// FaceTrackStepper (the solver's poses with the eyelids' seeded blinks; without
// them for settings.outputs.mesh.no_blinks; the fast solve's for
// settings.outputs.mesh.solve = FAST) (bit for bit as float32, within half
// a quantisation step as int16), Render =
// Animate, subscribers get the producer's mesh, channel-only streams carry no
// mesh bytes, bad mesh settings rejected naming the field; and, measured on the
// streamed mesh and ARKit weights of real TTS timings, sealed lips at every
// bilabial key frame and the lower lip at the upper teeth at every labiodental one.
#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../support/child_process.hpp"
#include "../support/lip_measures.hpp"
#include "../support/server_harness.hpp"
#include "lipsync/face/face_animation.hpp"
#include "lipsync/face/face_mesh.hpp"
#include "lipsync/face/face_rig.hpp"
#include "lipsync/face/face_solver.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/server/config.hpp"
#include "lipsync/server/server.hpp"
#include "lipsync/synthetic.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace lipsync::server {
namespace {

using harness::eventually;
using harness::to_proto;
using ::testing::HasSubstr;
using namespace std::chrono_literals;

std::vector<LabeledInterval> utterance(std::size_t phonemes, std::uint64_t seed = 3) {
  return synthesize_utterance({.phonemes = phonemes, .seed = seed});
}

Track reference_track(const std::vector<LabeledInterval>& intervals) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  return render_track(model, build_segments({"test", "", intervals}, model, arpabet), {.fps = 30});
}

/// The solver alone, offline: one step per frame, dt = t_i − t_{i−1} (t_{−1} = 0). Metres, double.
std::vector<double> solver_positions(const Track& track, int level) {
  const face::FaceMesh mesh = face::build_face_mesh(face::FaceAsset::builtin(), level);
  face::FaceSolver solver(mesh, face::FaceRig::builtin());
  std::vector<double> out;
  std::int64_t previous = 0;
  for (std::size_t frame = 0; frame < track.frame_count(); ++frame) {
    solver.step(track.frame_values(frame), static_cast<double>(track.t_us[frame] - previous) * 1e-6);
    previous = track.t_us[frame];
    for (const face::Vec3& p : solver.positions()) out.insert(out.end(), {p.x, p.y, p.z});
  }
  return out;
}

/// The documented rule, offline: the solver stepped as above, then the eyelids of the default
/// blink schedule (face::FaceTrackStepper). Metres, double.
std::vector<double> reference_positions(const Track& track, int level, const face::FaceSolverParams& params = {}) {
  const face::FaceMesh mesh = face::build_face_mesh(face::FaceAsset::builtin(), level);
  face::FaceSolver solver(mesh, face::FaceRig::builtin(), params);
  face::FaceTrackStepper stepper(solver);
  std::vector<double> out;
  for (std::size_t frame = 0; frame < track.frame_count(); ++frame)
    for (const face::Vec3& p : stepper.step(track.t_us[frame], track.frame_values(frame)))
      out.insert(out.end(), {p.x, p.y, p.z});
  return out;
}

v1::AnimationSettings mesh_settings(int level, v1::MeshEncoding encoding = v1::MESH_ENCODING_FLOAT32) {
  v1::AnimationSettings settings;
  auto& mesh = *settings.mutable_outputs()->mutable_mesh();
  mesh.set_enabled(true);
  mesh.set_subdivision(static_cast<std::uint32_t>(level));
  mesh.set_encoding(encoding);
  return settings;
}

struct Received {
  std::vector<v1::TrackHeader> headers;
  std::vector<v1::FrameBatch> batches;
  std::optional<v1::TrackSummary> summary;
  grpc::Status status;

  std::size_t frames() const {
    std::size_t n = 0;
    for (const auto& batch : batches) n += static_cast<std::size_t>(batch.t_us_size());
    return n;
  }
  std::vector<float> positions() const {
    std::vector<float> out;
    for (const auto& batch : batches)
      out.insert(out.end(), batch.mesh_positions().begin(), batch.mesh_positions().end());
    return out;
  }
  std::vector<std::int16_t> quantised() const {
    std::vector<std::int16_t> out;
    for (const auto& batch : batches) {
      const std::string& bytes = batch.mesh_positions_int16();
      for (std::size_t i = 0; i + 1 < bytes.size(); i += 2) {
        const auto low = static_cast<std::uint8_t>(bytes[i]), high = static_cast<std::uint8_t>(bytes[i + 1]);
        out.push_back(static_cast<std::int16_t>(static_cast<std::uint16_t>(low | (high << 8))));
      }
    }
    return out;
  }
  std::vector<float> values() const {
    std::vector<float> out;
    for (const auto& batch : batches) out.insert(out.end(), batch.values().begin(), batch.values().end());
    return out;
  }
};

void take(Received& received, const v1::TrackMessage& message) {
  if (message.has_header()) received.headers.push_back(message.header());
  if (message.has_frames()) received.batches.push_back(message.frames());
  if (message.has_summary()) received.summary = message.summary();
}

void set_deadline(grpc::ClientContext& context) { context.set_deadline(std::chrono::system_clock::now() + 60s); }

class MeshTest : public ::testing::Test {
 protected:
  void SetUp() override { start({}); }
  void start(ServerConfig config) {
    if (server_) server_->shutdown(0ms);
    config.listen = "127.0.0.1:0";
    config.log_level = "warn";
    config.face_priority = "normal";  // with ctest -j2, an idle-priority face would wait for the other test
    server_ = std::make_unique<Server>(config);
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(-1);
    stub_ =
        v1::LipSync::NewStub(grpc::CreateCustomChannel(server_->address(), grpc::InsecureChannelCredentials(), args));
  }
  void TearDown() override { server_->shutdown(0ms); }

  Received animate(const v1::AnimationSettings& settings, const std::vector<LabeledInterval>& intervals,
                   std::size_t chunk = 5) {
    grpc::ClientContext context;
    set_deadline(context);
    auto stream = stub_->Animate(&context);
    Received received;
    std::thread reader([&] {
      v1::TrackMessage message;
      while (stream->Read(&message)) take(received, message);
    });
    v1::AnimateRequest request;
    *request.mutable_settings() = settings;
    stream->Write(request);
    for (std::size_t i = 0; i < intervals.size(); i += chunk) {
      v1::AnimateRequest phonemes;
      for (std::size_t j = i; j < std::min(intervals.size(), i + chunk); ++j) {
        *phonemes.mutable_phonemes()->add_phonemes() = to_proto(intervals[j]);
      }
      if (!stream->Write(phonemes)) break;
    }
    v1::AnimateRequest end;
    end.mutable_end();
    stream->Write(end);
    stream->WritesDone();
    reader.join();
    received.status = stream->Finish();
    return received;
  }

  grpc::Status render(const v1::AnimationSettings& settings, const std::vector<LabeledInterval>& intervals,
                      v1::RenderResponse& response) {
    grpc::ClientContext context;
    set_deadline(context);
    v1::RenderRequest request;
    *request.mutable_settings() = settings;
    for (const auto& interval : intervals) *request.add_phonemes() = to_proto(interval);
    return stub_->Render(&context, request, &response);
  }

  std::unique_ptr<Server> server_;
  std::unique_ptr<v1::LipSync::Stub> stub_;
};

void expect_topology(const v1::TrackHeader& header, int level) {
  const face::FaceMesh mesh = face::build_face_mesh(face::FaceAsset::builtin(), level);
  ASSERT_TRUE(header.has_mesh());
  const v1::MeshTopology& topology = header.mesh();
  const std::size_t vertices = mesh.vertex_count();
  EXPECT_EQ(topology.subdivision(), static_cast<std::uint32_t>(level));
  EXPECT_EQ(topology.vertex_count(), vertices);
  EXPECT_EQ(topology.soft_vertex_count(), mesh.soft_node_count);
  EXPECT_EQ(topology.units(), "m");
  ASSERT_EQ(static_cast<std::size_t>(topology.rest_positions_size()), vertices * 3);
  ASSERT_EQ(static_cast<std::size_t>(topology.triangles_size()), mesh.triangles.size() * 3);
  ASSERT_EQ(static_cast<std::size_t>(topology.uvs_size()), vertices * 2);
  ASSERT_EQ(static_cast<std::size_t>(topology.parts_size()), vertices);
  for (std::size_t v = 0; v < vertices; v += 97) {
    EXPECT_EQ(topology.rest_positions(static_cast<int>(v * 3 + 1)), static_cast<float>(mesh.rest_positions_m[v].y));
    EXPECT_EQ(topology.uvs(static_cast<int>(v * 2)), mesh.uvs[v][0]);
    EXPECT_EQ(topology.parts(static_cast<int>(v)), static_cast<int>(mesh.parts[v]));
  }
  for (std::size_t t = 0; t < mesh.triangles.size(); t += 101) {
    EXPECT_EQ(topology.triangles(static_cast<int>(t * 3 + 2)), mesh.triangles[t][2]);
  }
}

TEST_F(MeshTest, AnimateFloat32EqualsTheOfflineSolverBitForBit) {
  const auto intervals = utterance(30);
  const Track track = reference_track(intervals);
  const Received received = animate(mesh_settings(1), intervals);
  ASSERT_TRUE(received.status.ok()) << received.status.error_message();
  ASSERT_EQ(received.headers.size(), 1u);
  expect_topology(received.headers[0], 1);
  EXPECT_EQ(received.headers[0].mesh().encoding(), v1::MESH_ENCODING_FLOAT32);
  const std::size_t vertices = received.headers[0].mesh().vertex_count();
  ASSERT_EQ(received.frames(), track.frame_count());
  for (const auto& batch : received.batches) {
    EXPECT_EQ(static_cast<std::size_t>(batch.mesh_positions_size()),
              static_cast<std::size_t>(batch.t_us_size()) * vertices * 3);
    EXPECT_TRUE(batch.mesh_positions_int16().empty());
    EXPECT_LE(batch.ByteSizeLong(), std::size_t{2} << 20);
  }
  EXPECT_EQ(received.values(), track.values);  // the channels are unchanged by the mesh
  const std::vector<double> expected = reference_positions(track, 1);
  std::vector<float> expected_float(expected.begin(), expected.end());
  EXPECT_TRUE(received.positions() == expected_float);
  // The face moves: some vertex leaves its rest position by more than 2 mm.
  const auto& rest = received.headers[0].mesh().rest_positions();
  float moved = 0;
  for (std::size_t i = 0; i < expected_float.size(); ++i) {
    moved = std::max(moved, std::abs(expected_float[i] - rest[static_cast<int>(i % (vertices * 3))]));
  }
  EXPECT_GT(moved, 0.002f);
}

TEST_F(MeshTest, NoBlinksStreamsTheSolversOwnPosesAndTheDefaultBlinksOnTheSchedule) {
  const auto intervals = utterance(30);
  const Track track = reference_track(intervals);
  ASSERT_GT(track.t_us.back(), face::kBlinkFirstUs + face::kBlinkCloseUs);  // the first blink is in it
  v1::AnimationSettings settings = mesh_settings(1);
  settings.mutable_outputs()->mutable_mesh()->set_no_blinks(true);
  const Received still = animate(settings, intervals);
  const Received blinking = animate(mesh_settings(1), intervals);
  ASSERT_TRUE(still.status.ok()) << still.status.error_message();
  ASSERT_TRUE(blinking.status.ok()) << blinking.status.error_message();
  const std::vector<double> solver_only = solver_positions(track, 1);
  EXPECT_TRUE(still.positions() == std::vector<float>(solver_only.begin(), solver_only.end()));
  EXPECT_FALSE(blinking.positions() == still.positions());
}

TEST_F(MeshTest, AStreamAfterAnotherStartsFromRestLikeANewSolver) {
  // Streams hand their solver back to the server's pool at the end; the next
  // stream's face must not remember the last utterance.
  const auto first = utterance(25, 31);
  const auto second = utterance(25, 32);
  const Track track = reference_track(second);
  const std::vector<double> expected = reference_positions(track, 0);
  const std::vector<float> expected_float(expected.begin(), expected.end());
  for (int round = 0; round < 3; ++round) {
    const Received warm_up = animate(mesh_settings(0), first);
    ASSERT_TRUE(warm_up.status.ok()) << warm_up.status.error_message();
    const Received received = animate(mesh_settings(0), second);
    ASSERT_TRUE(received.status.ok()) << received.status.error_message();
    EXPECT_TRUE(received.positions() == expected_float) << "round " << round;
  }
}

TEST_F(MeshTest, Int16IsWithinHalfAQuantisationStep) {
  const auto intervals = utterance(25, 7);
  const Track track = reference_track(intervals);
  const Received received = animate(mesh_settings(0, v1::MESH_ENCODING_INT16), intervals, 3);
  ASSERT_TRUE(received.status.ok()) << received.status.error_message();
  ASSERT_EQ(received.headers.size(), 1u);
  expect_topology(received.headers[0], 0);
  const v1::MeshTopology& topology = received.headers[0].mesh();
  EXPECT_EQ(topology.encoding(), v1::MESH_ENCODING_INT16);
  ASSERT_EQ(topology.quantisation_offset_m_size(), 3);
  const double scale = topology.quantisation_scale_m();
  EXPECT_GT(scale, 0.0);
  EXPECT_LT(scale, 1e-5);  // finer than 10 µm
  for (const auto& batch : received.batches) {
    EXPECT_EQ(batch.mesh_positions_size(), 0);
    EXPECT_EQ(batch.mesh_positions_int16().size(),
              static_cast<std::size_t>(batch.t_us_size()) * topology.vertex_count() * 3 * 2);
  }
  const std::vector<std::int16_t> q = received.quantised();
  const std::vector<double> expected = reference_positions(track, 0);
  ASSERT_EQ(q.size(), expected.size());
  double worst = 0;
  for (std::size_t i = 0; i < q.size(); ++i) {
    const double decoded = topology.quantisation_offset_m(static_cast<int>(i % 3)) + scale * q[i];
    worst = std::max(worst, std::abs(decoded - expected[i]));
  }
  EXPECT_LE(worst, scale * 0.5 + 1e-7);
}

TEST_F(MeshTest, RenderEqualsAnimate) {
  const auto intervals = utterance(20, 11);
  for (const auto encoding : {v1::MESH_ENCODING_FLOAT32, v1::MESH_ENCODING_INT16}) {
    const Received streamed = animate(mesh_settings(0, encoding), intervals, 4);
    ASSERT_TRUE(streamed.status.ok()) << streamed.status.error_message();
    v1::RenderResponse response;
    const grpc::Status status = render(mesh_settings(0, encoding), intervals, response);
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_EQ(response.header().SerializeAsString(), streamed.headers.at(0).SerializeAsString());
    Received rendered;
    rendered.batches.push_back(response.frames());
    EXPECT_EQ(rendered.frames(), streamed.frames());
    EXPECT_TRUE(rendered.positions() == streamed.positions());
    EXPECT_TRUE(rendered.quantised() == streamed.quantised());
    EXPECT_FALSE(encoding == v1::MESH_ENCODING_FLOAT32 ? rendered.positions().empty() : rendered.quantised().empty());
  }
}

TEST_F(MeshTest, ChannelOnlyStreamsCarryNoMeshBytes) {
  const auto intervals = utterance(20, 5);
  const Track track = reference_track(intervals);
  v1::AnimationSettings settings;
  settings.mutable_outputs()->set_channels(true);
  settings.mutable_outputs()->mutable_mesh()->set_subdivision(2);  // ignored: not enabled
  const Received received = animate(settings, intervals);
  ASSERT_TRUE(received.status.ok()) << received.status.error_message();
  EXPECT_FALSE(received.headers.at(0).has_mesh());
  for (const auto& batch : received.batches) {
    v1::FrameBatch plain;  // the same frames as the server sent before the mesh existed
    plain.set_first_frame(batch.first_frame());
    *plain.mutable_t_us() = batch.t_us();
    *plain.mutable_kinds() = batch.kinds();
    *plain.mutable_values() = batch.values();
    plain.set_release_lag_us(batch.release_lag_us());  // every stream's batches say this (not a mesh byte)
    EXPECT_EQ(batch.ByteSizeLong(), plain.ByteSizeLong());
    EXPECT_EQ(batch.mesh_positions_size(), 0);
    EXPECT_TRUE(batch.mesh_positions_int16().empty());
  }
  EXPECT_EQ(received.values(), track.values);
  v1::RenderResponse response;
  ASSERT_TRUE(render(settings, intervals, response).ok());
  EXPECT_FALSE(response.header().has_mesh());
  EXPECT_EQ(response.frames().mesh_positions_size(), 0);
  EXPECT_TRUE(response.frames().mesh_positions_int16().empty());
}

TEST_F(MeshTest, SubscriberGetsTheTopologyAndThePositions) {
  const auto intervals = utterance(20, 9);
  auto settings = mesh_settings(0);
  settings.set_session("face");
  Received subscribed;
  grpc::ClientContext subscribe_context;
  set_deadline(subscribe_context);
  std::unique_ptr<grpc::ClientReader<v1::TrackMessage>> reader;
  std::thread follower;
  // The producer opens the session; a live subscriber joins once it exists.
  grpc::ClientContext producer_context;
  set_deadline(producer_context);
  auto stream = stub_->Animate(&producer_context);
  v1::AnimateRequest request;
  *request.mutable_settings() = settings;
  ASSERT_TRUE(stream->Write(request));
  v1::TrackMessage message;
  ASSERT_TRUE(stream->Read(&message));
  Received produced;
  take(produced, message);
  v1::SubscribeRequest subscribe;
  subscribe.set_session("face");
  reader = stub_->Subscribe(&subscribe_context, subscribe);
  follower = std::thread([&] {
    v1::TrackMessage m;
    while (reader->Read(&m)) take(subscribed, m);
  });
  std::thread producer_reader([&] {
    v1::TrackMessage m;
    while (stream->Read(&m)) take(produced, m);
  });
  for (std::size_t i = 0; i < intervals.size(); i += 4) {
    v1::AnimateRequest chunk;
    for (std::size_t j = i; j < std::min(intervals.size(), i + 4); ++j) {
      *chunk.mutable_phonemes()->add_phonemes() = to_proto(intervals[j]);
    }
    ASSERT_TRUE(stream->Write(chunk));
  }
  v1::AnimateRequest end;
  end.mutable_end();
  ASSERT_TRUE(stream->Write(end));
  stream->WritesDone();
  producer_reader.join();
  ASSERT_TRUE(stream->Finish().ok());
  follower.join();
  subscribed.status = reader->Finish();
  ASSERT_TRUE(subscribed.status.ok()) << subscribed.status.error_message();
  ASSERT_EQ(subscribed.headers.size(), 1u);
  expect_topology(subscribed.headers[0], 0);
  EXPECT_EQ(subscribed.headers[0].SerializeAsString(), produced.headers.at(0).SerializeAsString());
  EXPECT_EQ(subscribed.frames(), produced.frames());
  EXPECT_TRUE(subscribed.positions() == produced.positions());
  EXPECT_FALSE(subscribed.positions().empty());
  EXPECT_TRUE(subscribed.summary.has_value());
}

TEST_F(MeshTest, FaceWorkRunsOffTheReactionsSoChannelStreamsAreNotHeldUp) {
  // Two mesh streams each send a whole utterance in one chunk: about a second of
  // solver work each, queued on the one face thread. Were it done inside the
  // reactions, it would occupy gRPC's callback threads and the channel-only
  // stream started after them would wait for it.
  ServerConfig config;
  config.face_threads = 1;
  // The six streams' whole tracks queue on one thread: under ctest -j2 the last
  // may start seconds late, which is what this test makes happen, not a failure.
  config.mesh_max_lag_ms = 60'000;
  start(config);
  const auto long_utterance = utterance(40, 21);
  const auto short_utterance = utterance(10, 22);
  std::atomic<int> finished_order{0};
  constexpr int kMeshStreams = 6;
  std::vector<int> mesh_finished(kMeshStreams, -1);
  std::vector<grpc::Status> mesh_status(kMeshStreams);
  std::vector<std::thread> mesh_streams;
  std::atomic<int> headers{0};
  for (int i = 0; i < kMeshStreams; ++i) {
    mesh_streams.emplace_back([&, i] {
      grpc::ClientContext context;
      set_deadline(context);
      auto stream = stub_->Animate(&context);
      v1::AnimateRequest request;
      *request.mutable_settings() = mesh_settings(1);
      stream->Write(request);
      v1::AnimateRequest phonemes;
      for (const auto& interval : long_utterance) *phonemes.mutable_phonemes()->add_phonemes() = to_proto(interval);
      stream->Write(phonemes);
      v1::AnimateRequest end;
      end.mutable_end();
      stream->Write(end);
      stream->WritesDone();
      v1::TrackMessage message;
      if (stream->Read(&message) && message.has_header()) ++headers;
      while (stream->Read(&message)) {
      }
      mesh_status[static_cast<std::size_t>(i)] = stream->Finish();
      mesh_finished[static_cast<std::size_t>(i)] = finished_order++;
    });
  }
  ASSERT_TRUE(eventually([&] { return headers.load() == kMeshStreams; }));
  const Received channels_only = animate(v1::AnimationSettings{}, short_utterance);
  const int channel_finished = finished_order++;
  for (auto& thread : mesh_streams) thread.join();
  ASSERT_TRUE(channels_only.status.ok()) << channels_only.status.error_message();
  EXPECT_EQ(channels_only.frames(), reference_track(short_utterance).frame_count());
  for (std::size_t i = 0; i < kMeshStreams; ++i) {
    ASSERT_TRUE(mesh_status[i].ok()) << mesh_status[i].error_message();
    EXPECT_GT(mesh_finished[i], channel_finished) << "mesh stream " << i << " finished before the channel stream";
  }
}

TEST_F(MeshTest, MeshStreamsBeyondTheFaceCapacityAreRefusedNamingTheLimit) {
  ServerConfig config;
  config.face_threads = 1;
  config.max_mesh_streams_per_face_thread = 1;  // one level-1, 30 fps stream
  start(config);
  // An admitted mesh stream, held open.
  grpc::ClientContext held_context;
  set_deadline(held_context);
  auto held = stub_->Animate(&held_context);
  v1::AnimateRequest settings_request;
  *settings_request.mutable_settings() = mesh_settings(1);
  ASSERT_TRUE(held->Write(settings_request));
  v1::TrackMessage header;
  ASSERT_TRUE(held->Read(&header));
  ASSERT_TRUE(header.has_header());

  const auto intervals = utterance(5);
  const Received refused = animate(mesh_settings(1), intervals);
  EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.status.error_message(), HasSubstr("--max-mesh-streams-per-face-thread=1 x 1 face threads"));
  EXPECT_THAT(refused.status.error_message(), HasSubstr("the face is at capacity"));
  v1::RenderResponse response;
  const grpc::Status refused_render = render(mesh_settings(0), intervals, response);
  EXPECT_EQ(refused_render.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused_render.error_message(), HasSubstr("--max-mesh-streams-per-face-thread=1"));
  // Bad settings are named as such even with the face full: they are checked before its capacity.
  auto bad_fps = mesh_settings(1);
  bad_fps.set_fps(241);
  const grpc::Status invalid_render = render(bad_fps, intervals, response);
  EXPECT_EQ(invalid_render.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << invalid_render.error_message();
  EXPECT_THAT(invalid_render.error_message(), HasSubstr("settings.fps"));
  // Streams without the mesh are not held to the face's capacity.
  const Received channels_only = animate(v1::AnimationSettings{}, intervals);
  ASSERT_TRUE(channels_only.status.ok()) << channels_only.status.error_message();
  EXPECT_EQ(channels_only.frames(), reference_track(intervals).frame_count());

  // Once the held stream ends, its share is free again.
  v1::AnimateRequest end;
  end.mutable_end();
  held->Write(end);
  held->WritesDone();
  v1::TrackMessage message;
  while (held->Read(&message)) {
  }
  ASSERT_TRUE(held->Finish().ok());
  EXPECT_TRUE(eventually([&] {
    v1::RenderResponse later;
    return render(mesh_settings(1), intervals, later).ok();
  }));
}

TEST_F(MeshTest, TheFastSolveStreamsTheOfflineFastSolversPosesAndSaysSoInTheHeader) {
  const auto intervals = utterance(30, 11);
  const Track track = reference_track(intervals);
  v1::AnimationSettings fast = mesh_settings(1);
  fast.mutable_outputs()->mutable_mesh()->set_solve(v1::MESH_SOLVE_FAST);
  const Received received = animate(fast, intervals);
  ASSERT_TRUE(received.status.ok()) << received.status.error_message();
  ASSERT_EQ(received.headers.size(), 1u);
  EXPECT_EQ(received.headers[0].mesh().solve(), v1::MESH_SOLVE_FAST);
  EXPECT_EQ(received.values(), track.values);  // the channels do not depend on the solve
  const std::vector<double> expected = reference_positions(track, 1, face::fast_face_solver_params());
  EXPECT_TRUE(received.positions() == std::vector<float>(expected.begin(), expected.end()));
  const std::vector<double> full = reference_positions(track, 1);
  EXPECT_FALSE(received.positions() == std::vector<float>(full.begin(), full.end()));
  v1::RenderResponse rendered;
  ASSERT_TRUE(render(fast, intervals, rendered).ok());
  EXPECT_EQ(rendered.header().mesh().solve(), v1::MESH_SOLVE_FAST);
  EXPECT_TRUE(std::vector<float>(rendered.frames().mesh_positions().begin(),
                                 rendered.frames().mesh_positions().end()) == received.positions());
  const Received unset = animate(mesh_settings(1), intervals);
  ASSERT_TRUE(unset.status.ok()) << unset.status.error_message();
  EXPECT_EQ(unset.headers[0].mesh().solve(), v1::MESH_SOLVE_FULL);
}

TEST_F(MeshTest, TwoFastLevel1StreamsAreAdmittedWhereOneFullOneFits) {
  ServerConfig config;
  config.face_threads = 1;
  config.max_mesh_streams_per_face_thread = 1;  // one level-1, 30 fps full solve
  start(config);
  v1::AnimationSettings fast = mesh_settings(1);
  fast.mutable_outputs()->mutable_mesh()->set_solve(v1::MESH_SOLVE_FAST);
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::unique_ptr<grpc::ClientReaderWriter<v1::AnimateRequest, v1::TrackMessage>>> held;
  for (int i = 0; i < 2; ++i) {
    contexts.push_back(std::make_unique<grpc::ClientContext>());
    set_deadline(*contexts.back());
    held.push_back(stub_->Animate(contexts.back().get()));
    v1::AnimateRequest settings_request;
    *settings_request.mutable_settings() = fast;
    ASSERT_TRUE(held.back()->Write(settings_request));
    v1::TrackMessage header;
    ASSERT_TRUE(held.back()->Read(&header)) << "fast stream " << i << " was not admitted";
    ASSERT_TRUE(header.has_header());
  }
  const Received refused = animate(fast, utterance(5));
  EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.status.error_message(),
              HasSubstr("the face is at capacity: mesh streams in progress weigh 0.9 and this one 0.4"));
  for (auto& stream : held) {
    v1::AnimateRequest end;
    end.mutable_end();
    stream->Write(end);
    stream->WritesDone();
    v1::TrackMessage message;
    while (stream->Read(&message)) {
    }
    EXPECT_TRUE(stream->Finish().ok());
  }
}

TEST_F(MeshTest, AMeshStreamThatFallsBehindRealTimeEndsWithDeadlineExceeded) {
  // Three level-2 faces at 240 fps on one thread need several times the CPU of
  // real time on any machine: they fall behind and must be told so quickly.
  ServerConfig config;
  config.face_threads = 1;
  config.max_mesh_streams_per_face_thread = 1000;
  config.mesh_max_lag_ms = 200;
  start(config);
  auto settings = mesh_settings(2);
  settings.set_fps(240);
  const auto intervals = utterance(40, 31);
  std::vector<grpc::Status> statuses(3);
  std::vector<std::thread> streams;
  for (std::size_t i = 0; i < statuses.size(); ++i) {
    streams.emplace_back([&, i] { statuses[i] = animate(settings, intervals, intervals.size()).status; });
  }
  for (auto& stream : streams) stream.join();
  for (const grpc::Status& status : statuses) {
    EXPECT_EQ(status.error_code(), grpc::StatusCode::DEADLINE_EXCEEDED) << status.error_message();
    EXPECT_THAT(status.error_message(), HasSubstr("behind real time, more than --mesh-max-lag-ms=200"));
  }
}

TEST_F(MeshTest, BadMeshSettingsAreRejectedNamingTheField) {
  const auto intervals = utterance(3);
  auto settings = mesh_settings(3);
  const Received received = animate(settings, intervals);
  EXPECT_EQ(received.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(received.status.error_message(), HasSubstr("settings.outputs.mesh.subdivision"));
  v1::RenderResponse response;
  const grpc::Status status = render(settings, intervals, response);
  EXPECT_EQ(status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(status.error_message(), HasSubstr("settings.outputs.mesh.subdivision"));
  settings = mesh_settings(1, static_cast<v1::MeshEncoding>(9));
  const grpc::Status encoding = render(settings, intervals, response);
  EXPECT_EQ(encoding.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(encoding.error_message(), HasSubstr("settings.outputs.mesh.encoding"));
  settings = mesh_settings(1);
  settings.mutable_outputs()->mutable_mesh()->set_solve(static_cast<v1::MeshSolve>(7));
  const grpc::Status solve = render(settings, intervals, response);
  EXPECT_EQ(solve.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(solve.error_message(), HasSubstr("settings.outputs.mesh.solve: unknown solve 7"));
}

// What a client sees: it sent the phonemes, it receives frames with kinds, ARKit weights and
// vertex positions. At each closure key frame it finds the phoneme being closed (the one that
// starts at a closure_start frame, the one that ends at a closure_end frame) and measures the mouth.
TEST_F(MeshTest, StreamedMeshAndArkitAreClosedAtEveryClosureKeyFrameOfRealSpeech) {
  const face::FaceMesh mesh = face::build_face_mesh(face::FaceAsset::builtin(), 1);
  const std::size_t jaw_open = 17, mouth_close = 18;
  ASSERT_EQ(kArkitNames[jaw_open], "jawOpen");
  ASSERT_EQ(kArkitNames[mouth_close], "mouthClose");
  std::size_t bilabial = 0, labiodental = 0;
  for (const char* name : {"festival_2.lab", "flite_3.psdur", "aligned_festival_3.TextGrid"}) {
    std::ifstream file(std::string(LIPSYNC_TEST_DATA_DIR) + "/closures/" + name);
    std::stringstream text;
    text << file.rdbuf();
    const InputFormat format = detect_input_format(name, text.str());
    const auto intervals = parse_utterance(text.str(), format, name).intervals;
    v1::AnimationSettings settings = mesh_settings(1);
    settings.set_phone_set(format == InputFormat::textgrid ? "arpabet" : "radio");  // PocketSphinx writes ARPAbet
    settings.mutable_outputs()->set_arkit(true);
    const Received received = animate(settings, intervals);
    ASSERT_TRUE(received.status.ok()) << received.status.error_message();
    const std::vector<float> positions = received.positions();
    const std::size_t vertices = mesh.vertex_count();
    std::vector<face::Vec3> pose(vertices);
    std::size_t frame = 0;
    for (const auto& batch : received.batches) {
      for (int k = 0; k < batch.t_us_size(); ++k, ++frame) {
        const auto kind = batch.kinds(k);
        if (kind != v1::FRAME_KIND_CLOSURE_START && kind != v1::FRAME_KIND_CLOSURE_END) continue;
        const std::int64_t t_us = batch.t_us(k);
        // The phoneme being closed: the one containing t (closure start) or t − 1 µs (closure end).
        const std::int64_t probe = kind == v1::FRAME_KIND_CLOSURE_START ? t_us : t_us - 1;
        std::string label;
        for (const auto& interval : intervals) {
          if (interval.start_us <= probe && probe < interval.end_us) label = interval.label;
        }
        for (std::size_t v = 0; v < vertices; ++v) {
          const float* p = positions.data() + (frame * vertices + v) * 3;
          pose[v] = {p[0], p[1], p[2]};
        }
        const float* arkit = batch.arkit().data() + static_cast<std::ptrdiff_t>(k) * 52;
        const std::string where = std::string(name) + " /" + label + "/ at " + std::to_string(t_us) + " µs";
        std::transform(label.begin(), label.end(), label.begin(), [](unsigned char c) { return std::tolower(c); });
        if (label == "p" || label == "b" || label == "m") {
          ++bilabial;
          EXPECT_LE(face::lip_gap_m(mesh, pose), 0.0005) << where;
          EXPECT_GE(arkit[mouth_close], arkit[jaw_open] - 0.02F) << where;
        } else if (label == "f" || label == "v") {
          ++labiodental;
          EXPECT_LE(face::lower_lip_to_upper_teeth_m(mesh, pose), 0.001) << where;
        } else {
          ADD_FAILURE() << where << ": a closure key frame on a phoneme that is not /p b m f v/";
        }
      }
    }
  }
  EXPECT_GE(bilabial, 10U);
  EXPECT_GE(labiodental, 4U);
}

/// The poses a glb holds: its key times (float seconds) and, per key, base + displacement.
struct GlbPoses {
  std::vector<float> times_s;
  std::vector<std::vector<double>> poses;  // per key: x y z per vertex
};

GlbPoses read_glb_poses(const std::string& bytes) {
  GlbPoses out;
  const auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, bytes.data() + at, 4);
    return v;
  };
  const std::uint32_t json_length = u32(12);
  const auto json = nlohmann::json::parse(bytes.substr(20, json_length));
  const std::size_t bin_at = 20 + json_length + 8;
  const auto floats = [&](std::size_t accessor) {
    const auto& a = json["accessors"][accessor];
    const auto& view = json["bufferViews"][a["bufferView"].get<std::size_t>()];
    const std::size_t components = a["type"] == "VEC3" ? 3 : 1;
    std::vector<float> values(a["count"].get<std::size_t>() * components);
    std::memcpy(values.data(), bytes.data() + bin_at + view["byteOffset"].get<std::size_t>(), values.size() * 4);
    return values;
  };
  const auto& primitive = json["meshes"][0]["primitives"][0];
  const std::vector<float> base = floats(primitive["attributes"]["POSITION"].get<std::size_t>());
  out.times_s = floats(json["animations"][0]["samplers"][0]["input"].get<std::size_t>());
  for (const auto& target : primitive["targets"]) {
    const std::vector<float> displacement = floats(target["POSITION"].get<std::size_t>());
    std::vector<double> pose(base.size());
    for (std::size_t i = 0; i < base.size(); ++i) pose[i] = static_cast<double>(base[i]) + displacement[i];
    out.poses.push_back(std::move(pose));
  }
  return out;
}

// One input, one face: `lipsync render --mesh` (the real CLI, default settings) writes the poses
// lipsyncd streams for the same phonemes and settings, and the video's frames are those poses on the
// --fps grid (face::resample_face_animation, what the CLI's --video and --still draw). Real speech:
// recorded LibriVox read speech aligned by PocketSphinx, TTS timings and an aligned TTS sentence.
TEST_F(MeshTest, LipsyncStreamWithMeshAndVisemesPublishesTheFaceAndTheVisemesWithoutChangingItsTrack) {
  const auto dir = lipsync::testing::make_temp_dir("lipsync-stream-mesh-");
  const std::string papa = std::string(LIPSYNC_TEST_DATA_DIR) + "/closures/flite_1.psdur";
  const auto stream = [&](const std::string& output, std::vector<std::string> options) {
    std::vector<std::string> args = {LIPSYNC_CLI_BINARY, "stream",           papa, "--fast",
                                     "--server",         server_->address(), "-o", output};
    args.insert(args.end(), options.begin(), options.end());
    return lipsync::testing::run_program(std::move(args), dir, dir);
  };
  const auto faced = stream("faced.json", {"--session", "faced", "--viewer-mesh", "--visemes", "oculus"});
  ASSERT_EQ(faced.status, 0) << faced.err;
  grpc::ClientContext context;
  set_deadline(context);
  v1::SubscribeRequest request;
  request.set_session("faced");
  auto reader = stub_->Subscribe(&context, request);
  Received subscribed;
  v1::TrackMessage message;
  while (reader->Read(&message)) take(subscribed, message);
  ASSERT_TRUE(reader->Finish().ok());
  ASSERT_EQ(subscribed.headers.size(), 1U);
  const v1::TrackHeader& header = subscribed.headers.front();
  ASSERT_TRUE(header.has_mesh());
  EXPECT_GT(header.mesh().vertex_count(), 0U);
  EXPECT_EQ(subscribed.positions().size(), subscribed.frames() * header.mesh().vertex_count() * 3);
  EXPECT_THAT(header.viseme_names(), ::testing::Contains("PP"));
  std::size_t events = 0;
  for (const auto& batch : subscribed.batches) events += static_cast<std::size_t>(batch.viseme_events_size());
  EXPECT_GT(events, 5U);

  const auto plain = stream("plain.json", {});
  ASSERT_EQ(plain.status, 0) << plain.err;
  EXPECT_EQ(lipsync::testing::read_text(dir / "faced.json"), lipsync::testing::read_text(dir / "plain.json"));

  const auto fast = stream("fast.json", {"--session", "fast", "--viewer-mesh", "--mesh-solve", "fast"});
  ASSERT_EQ(fast.status, 0) << fast.err;
  grpc::ClientContext fast_context;
  set_deadline(fast_context);
  request.set_session("fast");
  auto fast_reader = stub_->Subscribe(&fast_context, request);
  Received fast_subscribed;
  while (fast_reader->Read(&message)) take(fast_subscribed, message);
  ASSERT_TRUE(fast_reader->Finish().ok());
  ASSERT_EQ(fast_subscribed.headers.size(), 1U);
  EXPECT_EQ(fast_subscribed.headers.front().mesh().solve(), v1::MESH_SOLVE_FAST);
  EXPECT_EQ(header.mesh().solve(), v1::MESH_SOLVE_FULL);
  EXPECT_EQ(lipsync::testing::read_text(dir / "fast.json"), lipsync::testing::read_text(dir / "plain.json"));

  const auto without_session = stream("x.json", {"--viewer-mesh"});
  EXPECT_EQ(without_session.status, 2);
  EXPECT_THAT(without_session.err, HasSubstr("--viewer-mesh needs --session"));
  const auto solve_alone = stream("x.json", {"--session", "x", "--mesh-solve", "fast"});
  EXPECT_EQ(solve_alone.status, 2);
  EXPECT_THAT(solve_alone.err, HasSubstr("--mesh-solve needs --viewer-mesh"));
  std::filesystem::remove_all(dir);
}

TEST_F(MeshTest, TheGlbTheVideoAndTheStreamedMeshAreOneFaceOnRealSpeech) {
  const auto dir = lipsync::testing::make_temp_dir("lipsync-one-face-");
  std::size_t compared_keys = 0;
  for (const std::string name :
       {"librivox/sense_and_sensibility_0870.TextGrid", "librivox/sense_and_sensibility_0920.TextGrid",
        "closures/festival_2.lab", "closures/aligned_flite_3.TextGrid"}) {
    const std::string path = std::string(LIPSYNC_TEST_DATA_DIR) + "/" + name;
    std::ifstream file(path);
    std::stringstream text;
    text << file.rdbuf();
    const InputFormat format = detect_input_format(name, text.str());
    const auto intervals = parse_utterance(text.str(), format, name).intervals;
    v1::AnimationSettings settings = mesh_settings(1);
    settings.set_phone_set(format == InputFormat::textgrid ? "arpabet" : "radio");
    const Received received = animate(settings, intervals);
    ASSERT_TRUE(received.status.ok()) << name << ": " << received.status.error_message();
    const std::vector<float> streamed = received.positions();
    std::vector<std::int64_t> t_us;
    for (const auto& batch : received.batches) t_us.insert(t_us.end(), batch.t_us().begin(), batch.t_us().end());
    const std::size_t values_per_pose = streamed.size() / t_us.size();

    const auto run =
        lipsync::testing::run_program({LIPSYNC_CLI_BINARY, "render", path, "--mesh", (dir / "face.glb").string(),
                                       "--phone-set", format == InputFormat::textgrid ? "arpabet" : "radio"},
                                      dir, dir);
    ASSERT_EQ(run.status, 0) << run.err;
    const GlbPoses glb = read_glb_poses(lipsync::testing::read_text(dir / "face.glb"));
    ASSERT_GE(glb.poses.size(), 10U) << name;
    // Its keys are streamed frames, their poses the streamed ones to float rounding.
    double worst_key_m = 0;
    std::size_t frame = 0;
    for (std::size_t k = 0; k < glb.poses.size(); ++k) {
      while (frame + 1 < t_us.size() && static_cast<float>(static_cast<double>(t_us[frame]) * 1e-6) < glb.times_s[k]) {
        ++frame;
      }
      ASSERT_EQ(static_cast<float>(static_cast<double>(t_us[frame]) * 1e-6), glb.times_s[k]) << name << " key " << k;
      ASSERT_EQ(glb.poses[k].size(), values_per_pose);
      for (std::size_t i = 0; i < values_per_pose; ++i) {
        worst_key_m = std::max(worst_key_m, std::abs(glb.poses[k][i] - streamed[frame * values_per_pose + i]));
      }
    }
    compared_keys += glb.poses.size();
    EXPECT_LT(worst_key_m, 1e-7) << name << ": the glb's poses are not the streamed ones";

    // Played as a glTF player plays it (linear between keys), the glb shows every streamed frame, and
    // every frame of the video (the streamed poses on the 30 fps grid, linear between streamed frames,
    // face::resample_face_animation as --video and --still draw them), within the CLI's key tolerance.
    const auto played = [&](double t_s, std::size_t i) {
      const auto after = std::upper_bound(glb.times_s.begin(), glb.times_s.end(), static_cast<float>(t_s));
      if (after == glb.times_s.begin()) return glb.poses.front()[i];
      if (after == glb.times_s.end()) return glb.poses.back()[i];
      const auto b = static_cast<std::size_t>(after - glb.times_s.begin()), a = b - 1;
      const double w = (t_s - glb.times_s[a]) / (glb.times_s[b] - glb.times_s[a]);
      return (1 - w) * glb.poses[a][i] + w * glb.poses[b][i];
    };
    double worst_frame_m = 0, worst_video_m = 0;
    for (std::size_t f = 0; f < t_us.size(); ++f) {
      for (std::size_t i = 0; i < values_per_pose; ++i) {
        worst_frame_m = std::max(worst_frame_m, std::abs(played(static_cast<double>(t_us[f]) * 1e-6, i) -
                                                         streamed[f * values_per_pose + i]));
      }
    }
    face::FaceAnimation stream_faces;
    stream_faces.vertex_count = values_per_pose / 3;
    stream_faces.t_us = t_us;
    for (std::size_t i = 0; i < streamed.size(); i += 3) {
      stream_faces.positions.push_back({streamed[i], streamed[i + 1], streamed[i + 2]});
    }
    const face::FaceAnimation video = face::resample_face_animation(stream_faces, 30);
    EXPECT_GE(video.t_us.back(), t_us.back());
    EXPECT_LT(video.t_us.back(), t_us.back() + 33'334);
    for (std::size_t k = 0; k < video.frame_count(); ++k) {
      const auto shown = video.frame(k);
      for (std::size_t v = 0; v < shown.size(); ++v) {
        const double t_s = static_cast<double>(video.t_us[k]) * 1e-6;
        worst_video_m =
            std::max({worst_video_m, std::abs(shown[v].x - played(t_s, 3 * v)),
                      std::abs(shown[v].y - played(t_s, 3 * v + 1)), std::abs(shown[v].z - played(t_s, 3 * v + 2))});
      }
    }
    std::printf(
        "[ measured ] %s: %zu glb keys of %zu streamed frames; keys vs streamed poses %.1g mm, the glb "
        "played at every streamed frame %.3f mm, at every video frame %.3f mm\n",
        name.c_str(), glb.poses.size(), t_us.size(), worst_key_m * 1e3, worst_frame_m * 1e3, worst_video_m * 1e3);
    EXPECT_LT(worst_frame_m, 0.000011) << name;  // the CLI's key tolerance, 0.01 mm
    EXPECT_LT(worst_video_m, 0.000011) << name;
  }
  EXPECT_GE(compared_keys, 200U);
}

}  // namespace
}  // namespace lipsync::server
