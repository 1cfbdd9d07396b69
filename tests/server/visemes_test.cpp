// The viseme output over the network (proto: OutputSelection.visemes): a real lipsyncd on
// 127.0.0.1:0. For every vocabulary, Animate in any chunking equals Render and both equal the
// core's offline visemes (compute_visemes, what `lipsync render --format visemes-*` writes);
// a subscriber and a mesh stream get the same visemes; a bad vocabulary is refused naming the
// field; a stream that does not ask carries no viseme bytes; and on a Festival utterance the
// streamed Oculus weights make PP win at every bilabial key frame (read through the C++ client
// library).
#include "lipsync/visemes.hpp"

#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <span>
#include <sstream>
#include <string>
#include <vector>

#include "../support/closure_frames.hpp"
#include "../support/server_harness.hpp"
#include "lipsync/client/animation_client.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace lipsync::server {
namespace {

using namespace harness;
using ::testing::HasSubstr;
using VisemeServerTest = LiveServerTest;

struct VocabularyCase {
  v1::VisemeVocabulary wire;
  VisemeOptions core;
  const char* rhubarb_shapes = nullptr;  // settings.outputs.visemes.rhubarb_extended_shapes, if set
};

const VocabularyCase kCases[] = {
    {v1::VISEME_VOCABULARY_OCULUS, {.vocabulary = VisemeVocabulary::oculus}},
    {v1::VISEME_VOCABULARY_AZURE, {.vocabulary = VisemeVocabulary::azure}},
    {v1::VISEME_VOCABULARY_POLLY, {.vocabulary = VisemeVocabulary::polly}},
    {v1::VISEME_VOCABULARY_RHUBARB, {.vocabulary = VisemeVocabulary::rhubarb}},
    {v1::VISEME_VOCABULARY_RHUBARB,
     {.vocabulary = VisemeVocabulary::rhubarb, .rhubarb_shapes = {.g = true, .h = false, .x = true}},
     "GX"},
};

v1::AnimationSettings viseme_settings(const VocabularyCase& c) {
  v1::AnimationSettings settings;
  settings.mutable_outputs()->set_channels(true);
  auto* visemes = settings.mutable_outputs()->mutable_visemes();
  visemes->set_enabled(true);
  visemes->set_vocabulary(c.wire);
  if (c.rhubarb_shapes) visemes->set_rhubarb_extended_shapes(c.rhubarb_shapes);
  return settings;
}

v1::RenderResponse render(v1::LipSync::Stub& stub, const v1::AnimationSettings& settings,
                          const std::vector<LabeledInterval>& intervals, grpc::Status& status) {
  v1::RenderRequest request;
  *request.mutable_settings() = settings;
  for (const auto& interval : intervals) *request.add_phonemes() = to_proto(interval);
  v1::RenderResponse response;
  grpc::ClientContext context;
  set_deadline(context);
  status = stub.Render(&context, request, &response);
  return response;
}

/// What `lipsync render --format visemes-*` computes for these phonemes (arpabet, 30 fps).
VisemeTrack offline_visemes(const std::vector<LabeledInterval>& intervals, const VisemeOptions& options) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet arpabet = *PhoneSet::builtin("arpabet", model);
  const Track track = render_track(model, build_segments({"test", "", intervals}, model, arpabet), {});
  return compute_visemes(VisemeClassifier(model, options), track);
}

std::vector<std::string> names_of(const v1::TrackHeader& header) {
  return {header.viseme_names().begin(), header.viseme_names().end()};
}

TEST_F(VisemeServerTest, AnimateEqualsRenderEqualsTheOfflineVisemesForEveryVocabulary) {
  const auto intervals = utterance(80, 21);
  for (const VocabularyCase& c : kCases) {
    SCOPED_TRACE(std::string(to_string(c.core.vocabulary)) + " " + to_string(c.core.rhubarb_shapes));
    const VisemeClassifier classifier(ArticulationModel::builtin(), c.core);
    const VisemeTrack offline = offline_visemes(intervals, c.core);
    ASSERT_GT(offline.events.size(), 10U);

    grpc::Status status;
    const v1::RenderResponse rendered = render(*stub_, viseme_settings(c), intervals, status);
    ASSERT_TRUE(status.ok()) << status.error_message();
    EXPECT_EQ(rendered.header().viseme_vocabulary(), c.wire);
    EXPECT_EQ(names_of(rendered.header()), classifier.names());
    Frames whole;
    whole.append(rendered.frames());
    EXPECT_EQ(whole.viseme_weights, offline.weights);
    EXPECT_EQ(whole.viseme_events, offline.events);

    for (const std::size_t chunk : {1U, 7U}) {
      SCOPED_TRACE("chunk " + std::to_string(chunk));
      const Received streamed = animate(*stub_, harness::whole(viseme_settings(c), intervals, chunk));
      ASSERT_TRUE(streamed.status.ok()) << streamed.status.error_message();
      EXPECT_EQ(names_of(*streamed.header), classifier.names());
      EXPECT_GT(streamed.batches, 1U);
      EXPECT_EQ(streamed.frames.t_us, whole.t_us);
      EXPECT_EQ(streamed.frames.values, whole.values);
      EXPECT_EQ(streamed.frames.viseme_weights, whole.viseme_weights);
      EXPECT_EQ(streamed.frames.viseme_events, whole.viseme_events);
    }
  }
}

TEST_F(VisemeServerTest, ASubscriberGetsTheProducersVisemes) {
  const auto intervals = utterance(60, 4);
  const VocabularyCase& azure = kCases[1];
  v1::AnimationSettings settings = viseme_settings(azure);
  settings.set_session("visemes");
  Producer producer(*stub_, settings);
  Subscriber subscriber(*stub_, "visemes", v1::SubscribeRequest::START_FROM_BEGINNING);
  ASSERT_TRUE(subscriber.attached());
  for (auto& request : chunked(intervals, 5)) producer.write(request);
  producer.write(end_request());
  const Received produced = producer.finish();
  const Received followed = subscriber.finish();
  ASSERT_TRUE(produced.status.ok()) << produced.status.error_message();
  ASSERT_TRUE(followed.status.ok()) << followed.status.error_message();
  EXPECT_EQ(names_of(*followed.header), names_of(*produced.header));
  const VisemeTrack offline = offline_visemes(intervals, azure.core);
  EXPECT_EQ(produced.frames.viseme_weights, offline.weights);
  EXPECT_EQ(followed.frames.viseme_weights, offline.weights);
  EXPECT_EQ(followed.frames.viseme_events, offline.events);
}

TEST_F(VisemeServerTest, AMeshStreamCarriesTheSameVisemesOneFrameAtATime) {
  const auto intervals = utterance(12, 6);
  const VocabularyCase& polly = kCases[2];
  v1::AnimationSettings settings = viseme_settings(polly);
  settings.mutable_outputs()->mutable_mesh()->set_enabled(true);
  settings.mutable_outputs()->mutable_mesh()->set_subdivision(0);
  const Received streamed = animate(*stub_, whole(settings, intervals, 3));
  ASSERT_TRUE(streamed.status.ok()) << streamed.status.error_message();
  const VisemeTrack offline = offline_visemes(intervals, polly.core);
  EXPECT_EQ(streamed.batches, streamed.frames.t_us.size());  // the mesh sends one frame per batch
  EXPECT_EQ(streamed.frames.viseme_weights, offline.weights);
  EXPECT_EQ(streamed.frames.viseme_events, offline.events);
}

TEST_F(VisemeServerTest, BadVisemeSettingsAreRefusedNamingTheField) {
  const auto intervals = utterance(10, 2);
  const auto refusal = [&](void (*change)(v1::VisemeOutput&)) {
    v1::AnimationSettings settings;
    settings.mutable_outputs()->mutable_visemes()->set_enabled(true);
    change(*settings.mutable_outputs()->mutable_visemes());
    grpc::Status rendered;
    render(*stub_, settings, intervals, rendered);
    const Received streamed = animate(*stub_, whole(settings, intervals, 5));
    EXPECT_EQ(streamed.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_EQ(streamed.status.error_message(), rendered.error_message());
    EXPECT_FALSE(streamed.header.has_value());
    return rendered;
  };
  const grpc::Status unknown =
      refusal([](v1::VisemeOutput& v) { v.set_vocabulary(static_cast<v1::VisemeVocabulary>(99)); });
  EXPECT_EQ(unknown.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(unknown.error_message(), HasSubstr("settings.outputs.visemes.vocabulary"));
  EXPECT_THAT(unknown.error_message(), HasSubstr("99"));

  const grpc::Status bad_shapes = refusal([](v1::VisemeOutput& v) {
    v.set_vocabulary(v1::VISEME_VOCABULARY_RHUBARB);
    v.set_rhubarb_extended_shapes("GQ");
  });
  EXPECT_EQ(bad_shapes.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(bad_shapes.error_message(), HasSubstr("settings.outputs.visemes.rhubarb_extended_shapes: 'GQ'"));

  const grpc::Status shapes_for_oculus = refusal([](v1::VisemeOutput& v) { v.set_rhubarb_extended_shapes("GHX"); });
  EXPECT_EQ(shapes_for_oculus.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(shapes_for_oculus.error_message(), HasSubstr("settings.outputs.visemes.rhubarb_extended_shapes"));
}

TEST_F(VisemeServerTest, StreamsThatDoNotAskCarryNoVisemeBytes) {
  const auto intervals = utterance(40, 9);
  v1::AnimationSettings channels_only;
  channels_only.mutable_outputs()->set_channels(true);
  channels_only.mutable_outputs()->mutable_visemes()->set_vocabulary(v1::VISEME_VOCABULARY_AZURE);  // not enabled
  std::size_t batches = 0;
  grpc::ClientContext context;
  set_deadline(context);
  auto stream = stub_->Animate(&context);
  for (const auto& request : whole(channels_only, intervals, 4)) ASSERT_TRUE(stream->Write(request));
  stream->WritesDone();
  v1::TrackMessage message;
  while (stream->Read(&message)) {
    if (message.has_header()) {
      EXPECT_EQ(message.header().viseme_names_size(), 0);
      EXPECT_EQ(message.header().viseme_vocabulary(), v1::VISEME_VOCABULARY_UNSPECIFIED);
    }
    if (!message.has_frames()) continue;
    ++batches;
    v1::FrameBatch without = message.frames();
    without.clear_viseme_weights();
    without.clear_viseme_events();
    EXPECT_EQ(message.frames().ByteSizeLong(), without.ByteSizeLong()) << "batch at " << message.frames().first_frame();
  }
  ASSERT_TRUE(stream->Finish().ok());
  EXPECT_GT(batches, 1U);
}

TEST_F(VisemeServerTest, PPWinsAtEveryBilabialKeyFrameOfAFestivalUtteranceInTheStreamedWeights) {
  const std::string name = "festival_2.lab";
  std::ifstream file(std::string(LIPSYNC_TEST_DATA_DIR) + "/closures/" + name, std::ios::binary);
  std::stringstream text;
  text << file.rdbuf();
  ASSERT_FALSE(text.str().empty()) << name;
  const LabeledUtterance spoken = parse_utterance(text.str(), detect_input_format(name, text.str()), name);
  const ArticulationModel& model = ArticulationModel::builtin();
  const std::vector<Segment> segments = build_segments(spoken, model, *PhoneSet::builtin("radio", model));
  const Track expected = render_track(model, segments, {});
  std::vector<std::size_t> bilabial_frames;
  for (const auto& closure : testing::closure_frames(model, segments, expected)) {
    if (closure.place == testing::ClosurePlace::bilabial) bilabial_frames.push_back(closure.frame);
  }
  ASSERT_GE(bilabial_frames.size(), 6U) << name;

  v1::AnimationSettings settings = viseme_settings(kCases[0]);
  settings.set_phone_set("radio");
  std::vector<std::vector<v1::Phoneme>> chunks(1);
  for (const auto& interval : spoken.intervals) {
    if (chunks.back().size() == 4) chunks.emplace_back();
    chunks.back().push_back(client::to_wire(interval));
  }
  std::size_t misplaced_events = 0;
  const client::AnimationClient lipsyncd(server_->address());
  const client::ReceivedTrack streamed = lipsyncd.animate(settings, chunks, [&](const v1::TrackMessage& message) {
    for (const auto& event : message.frames().viseme_events()) {  // each in the batch where it starts
      const auto& t_us = message.frames().t_us();
      if (std::find(t_us.begin(), t_us.end(), event.start_us()) == t_us.end()) ++misplaced_events;
    }
  });
  EXPECT_EQ(misplaced_events, 0U);
  ASSERT_EQ(streamed.track.t_us, expected.t_us);
  const std::size_t visemes = static_cast<std::size_t>(streamed.header.viseme_names_size());
  ASSERT_EQ(streamed.viseme_weights.size(), expected.frame_count() * visemes);
  ASSERT_EQ(streamed.header.viseme_names(1), "PP");
  for (const std::size_t frame : bilabial_frames) {
    const std::span<const float> weights(streamed.viseme_weights.data() + frame * visemes, visemes);
    EXPECT_EQ(streamed.header.viseme_names(static_cast<int>(VisemeClassifier::winner(weights))), "PP")
        << name << ": bilabial key frame " << frame << " at " << expected.t_us[frame] << " µs";
    // A PP event holds at the frame: the last event at or before it.
    const auto after =
        std::upper_bound(streamed.viseme_events.begin(), streamed.viseme_events.end(), expected.t_us[frame],
                         [](std::int64_t t_us, const VisemeEvent& e) { return t_us < e.start_us; });
    ASSERT_NE(after, streamed.viseme_events.begin());
    EXPECT_EQ(std::prev(after)->viseme, 1U) << "at " << expected.t_us[frame] << " µs";
  }
}

}  // namespace
}  // namespace lipsync::server
