// The Speak RPC on a real lipsyncd (127.0.0.1:0) with the real espeak-ng: the
// frames equal the core's offline render of the phonemes espeak-ng reports
// through lipsync::speech::synthesize (the call `lipsync say` makes) after
// cover_audio, and the audio equals its samples; the track's last frame is at or
// after the audio's end and within one frame step of it; audio and frames arrive
// in utterance-time order; a subscriber of the session gets the same frames; bad
// input and full servers get the right status with a message naming the field;
// and `lipsync speak` writes what `lipsync say` writes, byte for byte.
#include <gmock/gmock.h>
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <future>
#include <string>
#include <thread>
#include <vector>

#include "../support/child_process.hpp"
#include "../support/prometheus_text.hpp"
#include "../support/server_harness.hpp"
#include "lipsync/client/animation_client.hpp"
#include "lipsync/model.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/renderer.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/speech/audio.hpp"
#include "lipsync/speech/synthesizer.hpp"
#include "lipsync/v1/lipsync.grpc.pb.h"

namespace lipsync::server {
namespace {

using namespace harness;
using ::testing::ElementsAreArray;
using ::testing::HasSubstr;

constexpr const char* kSentences[] = {"Papa parked the car.", "Where were you, Bob? Mum waved from the ferry."};

v1::SpeakRequest speak_request(const std::string& text, const std::string& session = "") {
  v1::SpeakRequest request;
  request.set_text(text);
  if (!session.empty()) request.mutable_settings()->set_session(session);
  return request;
}

/// What espeak-ng says for `text` and the phonemes a track of it at `fps` is rendered from (`lipsync say`'s steps).
speech::Synthesis spoken_locally(const std::string& text, int fps) {
  speech::Synthesis speech = speech::synthesize(text);
  speech::cover_audio(speech.phonemes, speech.audio.duration_us(), fps);
  return speech;
}

/// Every message of one Speak call, in order, and its status.
struct SpeakStream {
  std::vector<v1::SpeakResponse> messages;
  grpc::Status status;
};

SpeakStream speak_raw(v1::LipSync::Stub& stub, const v1::SpeakRequest& request) {
  grpc::ClientContext context;
  set_deadline(context);
  auto reader = stub.Speak(&context, request);
  SpeakStream stream;
  v1::SpeakResponse message;
  while (reader->Read(&message)) stream.messages.push_back(message);
  stream.status = reader->Finish();
  return stream;
}

class SpeakTest : public LiveServerTest {
 protected:
  client::SpokenTrack speak(const v1::SpeakRequest& request) {
    return client::AnimationClient(server_->address()).speak(request);
  }
};

TEST_F(SpeakTest, FramesEqualTheOfflineRenderOfThePhonemesEspeakReports) {
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet espeak = *PhoneSet::builtin("espeak", model);
  for (const char* text : kSentences) {
    SCOPED_TRACE(text);
    const speech::Synthesis local = spoken_locally(text, 30);
    const Track offline = render_track(model, build_segments(local.phonemes, model, espeak));
    const client::SpokenTrack spoken = speak(speak_request(text));

    std::vector<v1::Phoneme> expected_phonemes;
    for (const LabeledInterval& interval : local.phonemes.intervals) expected_phonemes.push_back(to_proto(interval));
    ASSERT_EQ(spoken.header.phonemes_size(), static_cast<int>(expected_phonemes.size()));
    for (int i = 0; i < spoken.header.phonemes_size(); ++i) {
      EXPECT_EQ(spoken.header.phonemes(i).SerializeAsString(),
                expected_phonemes[static_cast<std::size_t>(i)].SerializeAsString())
          << "phoneme " << i;
    }
    EXPECT_EQ(spoken.header.track().fps(), 30U);
    EXPECT_EQ(spoken.track.track.channel_count, model.channel_count());
    EXPECT_THAT(spoken.track.track.t_us, ElementsAreArray(offline.t_us));
    EXPECT_THAT(spoken.track.track.kinds, ElementsAreArray(offline.kinds));
    EXPECT_THAT(spoken.track.track.values, ElementsAreArray(offline.values));  // exact floats: bit for bit
    ASSERT_TRUE(spoken.summary.has_value());
    EXPECT_EQ(spoken.summary->track().frames(), offline.frame_count());
    EXPECT_EQ(spoken.summary->track().duration_us(), local.phonemes.intervals.back().end_us);
  }
}

TEST_F(SpeakTest, OtherLanguagesSpeakThroughTheIpaPhoneSetAndEqualTheirOfflineRender) {
  // Non-English voices name their phonemes in IPA (docs/languages.md); Speak renders them with the
  // ipa set, and asking for espeak's mnemonics with such a voice is refused naming the right set.
  const ArticulationModel& model = ArticulationModel::builtin();
  const PhoneSet ipa = *PhoneSet::builtin("ipa", model);
  for (const auto& [voice, text] : {std::pair{"de", "Guten Morgen, wie geht es Ihnen?"},
                                    std::pair{"fr-fr", "Un bon vin blanc."}, std::pair{"ru", "Мама мыла раму."}}) {
    SCOPED_TRACE(voice);
    speech::SynthesisOptions options;
    options.voice = voice;
    speech::Synthesis local = speech::synthesize(text, options);
    EXPECT_EQ(local.phonemes.phone_set, "ipa");
    speech::cover_audio(local.phonemes, local.audio.duration_us(), 30);
    const Track offline = render_track(model, build_segments(local.phonemes, model, ipa));
    v1::SpeakRequest request = speak_request(text);
    request.set_voice(voice);
    const client::SpokenTrack spoken = speak(request);
    EXPECT_EQ(spoken.header.phonemes_size(), static_cast<int>(local.phonemes.intervals.size()));
    EXPECT_THAT(spoken.track.track.values, ElementsAreArray(offline.values));
    request.mutable_settings()->set_phone_set("espeak");
    const SpeakStream refused = speak_raw(*stub_, request);
    EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(refused.status.error_message(), HasSubstr("leave it empty or 'ipa'"));
  }
}

TEST_F(SpeakTest, EveryEspeakVoiceSpeaks) {
  // Every voice espeak-ng has, by its file name, through Speak: audio and frames come back.
  std::size_t spoken_voices = 0;
  for (const speech::Voice& voice : speech::list_voices()) {
    SCOPED_TRACE(voice.identifier);
    v1::SpeakRequest request = speak_request("1 2 3 sagwu tali");  // Cherokee reads only Latin letters
    request.set_voice(voice.identifier);
    const SpeakStream stream = speak_raw(*stub_, request);
    EXPECT_TRUE(stream.status.ok()) << stream.status.error_message();
    bool frames = false;
    for (const v1::SpeakResponse& message : stream.messages) frames = frames || message.has_frames();
    EXPECT_TRUE(frames);
    spoken_voices += stream.status.ok() && frames;
  }
  EXPECT_GE(spoken_voices, 131U);
}

TEST_F(SpeakTest, AudioEqualsTheSamplesEspeakGivesAndIsDescribedByTheHeader) {
  const speech::Synthesis local = spoken_locally(kSentences[0], 30);
  const client::SpokenTrack spoken = speak(speak_request(kSentences[0]));
  EXPECT_EQ(spoken.header.sample_rate_hz(), static_cast<std::uint32_t>(local.audio.sample_rate_hz));
  EXPECT_EQ(spoken.header.channels(), 1U);
  EXPECT_EQ(spoken.header.sample_format(), v1::SAMPLE_FORMAT_PCM_S16LE);
  EXPECT_EQ(spoken.header.sample_count(), local.audio.samples.size());
  EXPECT_EQ(spoken.header.audio_duration_us(), local.audio.duration_us());
  EXPECT_EQ(spoken.header.voice(), "en-us");
  EXPECT_EQ(spoken.header.words_per_minute(), 175U);
  EXPECT_TRUE(spoken.samples == local.audio.samples) << "the samples differ from espeak-ng's";
  ASSERT_TRUE(spoken.summary.has_value());
  EXPECT_EQ(spoken.summary->sample_count(), local.audio.samples.size());
}

TEST_F(SpeakTest, LastFrameIsAtOrAfterTheEndOfTheAudioAndWithinOneFrameStep) {
  for (const std::uint32_t fps : {24U, 30U, 60U}) {
    SCOPED_TRACE("fps " + std::to_string(fps));
    v1::SpeakRequest request = speak_request(kSentences[1]);
    request.mutable_settings()->set_fps(fps);
    const client::SpokenTrack spoken = speak(request);
    const std::int64_t audio_end_us = spoken.header.audio_duration_us();
    const std::int64_t step_us = (1'000'000 + fps - 1) / fps;
    ASSERT_FALSE(spoken.track.track.t_us.empty());
    EXPECT_GE(spoken.track.track.t_us.back(), audio_end_us);
    EXPECT_LT(spoken.track.track.t_us.back(), audio_end_us + step_us);
  }
}

TEST_F(SpeakTest, AudioChunksContinueEachOtherAndComeBeforeTheFramesTheySoundUnder) {
  const SpeakStream stream = speak_raw(*stub_, speak_request(kSentences[1]));
  ASSERT_TRUE(stream.status.ok()) << stream.status.error_message();
  ASSERT_TRUE(stream.messages.front().has_header());
  ASSERT_TRUE(stream.messages.back().has_summary());
  const v1::SpeakHeader& header = stream.messages.front().header();
  std::uint64_t samples = 0;
  std::int64_t last_frame_us = -1;
  for (const v1::SpeakResponse& message : stream.messages) {
    if (message.has_audio()) {
      const v1::AudioChunk& chunk = message.audio();
      EXPECT_EQ(chunk.first_sample(), samples);
      EXPECT_EQ(chunk.start_us(), static_cast<std::int64_t>(samples * 1'000'000 / header.sample_rate_hz()));
      EXPECT_GT(chunk.start_us(), last_frame_us)
          << "a frame at " << last_frame_us << " us came before the audio chunk starting at " << chunk.start_us();
      samples += chunk.pcm().size() / 2;
    }
    if (message.has_frames()) last_frame_us = message.frames().t_us(message.frames().t_us_size() - 1);
  }
  EXPECT_EQ(samples, header.sample_count());
}

TEST_F(SpeakTest, ASubscriberOfTheSessionGetsTheSameFrames) {
  v1::SpeakRequest request = speak_request(kSentences[1], "speaker");
  request.mutable_settings()->mutable_media_clock()->set_clock("unix");
  request.mutable_settings()->mutable_media_clock()->set_utterance_zero_us(1'700'000'000'000'000);
  grpc::ClientContext context;
  set_deadline(context);
  auto reader = stub_->Speak(&context, request);
  v1::SpeakResponse message;
  ASSERT_TRUE(reader->Read(&message));
  ASSERT_TRUE(message.has_header());  // the session is open from the call's start
  const v1::SpeakHeader header = message.header();
  Received subscribed;
  std::thread subscriber([&] { subscribed = subscribe_all(*stub_, "speaker"); });
  client::SpokenTrack spoken;
  spoken.add(message);
  while (reader->Read(&message)) spoken.add(message);
  ASSERT_TRUE(reader->Finish().ok());
  subscriber.join();

  ASSERT_TRUE(subscribed.status.ok()) << subscribed.status.error_message();
  ASSERT_TRUE(subscribed.header.has_value());
  EXPECT_EQ(subscribed.header->SerializeAsString(), header.track().SerializeAsString());
  EXPECT_EQ(subscribed.header->session(), "speaker");
  EXPECT_EQ(subscribed.header->media_clock().utterance_zero_us(), 1'700'000'000'000'000);
  EXPECT_THAT(subscribed.frames.t_us, ElementsAreArray(spoken.track.track.t_us));
  EXPECT_THAT(subscribed.frames.values, ElementsAreArray(spoken.track.track.values));
  EXPECT_THAT(subscribed.frames.arkit, ElementsAreArray(spoken.track.arkit));
  ASSERT_TRUE(subscribed.summary.has_value());
  EXPECT_EQ(subscribed.summary->SerializeAsString(), spoken.summary->track().SerializeAsString());
}

struct BadRequest {
  const char* what;
  v1::SpeakRequest request;
  const char* field;   // the message names it
  const char* detail;  // and says this
};

TEST_F(SpeakTest, BadRequestsAreRefusedNamingTheField) {
  std::vector<BadRequest> cases;
  cases.push_back({"empty text", speak_request(""), "text:", "empty"});
  cases.push_back({"white space only", speak_request(" \n\t"), "text:", "empty"});
  cases.push_back({"text over the limit", speak_request(std::string(4097, 'a')), "text:", "4096 bytes"});
  cases.push_back({"unknown voice", speak_request("Hello."), "voice:", "'no-such-voice'"});
  cases.back().request.set_voice("no-such-voice");
  cases.push_back({"a voice's name, not its file", speak_request("Bonjour."),
                   "voice:", "unknown voice 'French'; close matches: fr (French (France))"});
  cases.back().request.set_voice("French");
  cases.push_back({"kanji in Japanese", speak_request("漢字です。"), "text:", "voice 'ja' cannot read '漢字です'"});
  cases.back().request.set_voice("ja");
  cases.push_back({"rate too high", speak_request("Hello."), "words_per_minute:", "500"});
  cases.back().request.set_words_per_minute(500);
  cases.push_back({"fps out of range", speak_request("Hello."), "settings.fps:", "241"});
  cases.back().request.mutable_settings()->set_fps(241);
  cases.push_back({"another phone set", speak_request("Hello."), "settings.phone_set:", "'arpabet'"});
  cases.back().request.mutable_settings()->set_phone_set("arpabet");
  cases.push_back({"mesh output", speak_request("Hello."), "settings.outputs.mesh:", "Render"});
  cases.back().request.mutable_settings()->mutable_outputs()->mutable_mesh()->set_enabled(true);
  cases.push_back({"unknown model", speak_request("Hello."), "settings.model:", "'nobody'"});
  cases.back().request.mutable_settings()->set_model("nobody");
  for (const BadRequest& bad : cases) {
    SCOPED_TRACE(bad.what);
    const SpeakStream stream = speak_raw(*stub_, bad.request);
    EXPECT_EQ(stream.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(stream.status.error_message(), HasSubstr(bad.field));
    EXPECT_THAT(stream.status.error_message(), HasSubstr(bad.detail));
    EXPECT_TRUE(stream.messages.empty());
  }
  // Refused calls leave the server and espeak-ng serving.
  EXPECT_TRUE(speak_raw(*stub_, speak_request("Hello.")).status.ok());
}

TEST_F(SpeakTest, ASessionNameInUseIsAlreadyExistsAndAnUnreadableTextAbortsItsSubscribers) {
  Producer producer(*stub_, session_settings("taken"));
  const SpeakStream taken = speak_raw(*stub_, speak_request("Hello.", "taken"));
  EXPECT_EQ(taken.status.error_code(), grpc::StatusCode::ALREADY_EXISTS) << taken.status.error_message();
  producer.cancel();

  // The text is found unreadable once spoken, after the session opened: its subscribers are told why.
  v1::SpeakRequest kanji = speak_request("漢字", "mute");
  kanji.set_voice("ja");
  EXPECT_EQ(speak_raw(*stub_, kanji).status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  const Received subscribed = subscribe_all(*stub_, "mute");
  EXPECT_EQ(subscribed.status.error_code(), grpc::StatusCode::ABORTED);
  EXPECT_THAT(subscribed.status.error_message(), HasSubstr("'漢字'"));
}

TEST_F(SpeakTest, WordsReadByAnotherLanguagesRulesAreNamedInTheSummaryAndByLipsyncSpeak) {
  v1::SpeakRequest request = speak_request("hello мир");
  request.set_voice("ru");
  const SpeakStream stream = speak_raw(*stub_, request);
  ASSERT_TRUE(stream.status.ok()) << stream.status.error_message();
  ASSERT_TRUE(stream.messages.back().has_summary());
  const auto& notes = stream.messages.back().summary().track().notes();
  ASSERT_EQ(notes.size(), 1);
  EXPECT_EQ(notes[0], "espeak-ng read 'hello' by the rules of another language (en), not those of voice 'ru'");

  namespace fs = std::filesystem;
  const fs::path dir = testing::make_temp_dir("lipsync-speak-notes-");
  const auto spoken = testing::run_program(
      {LIPSYNC_CLI_BINARY, "speak", "hello мир", "--voice", "ru", "--server", server_->address(), "-o", "t.json"}, dir,
      dir);
  EXPECT_EQ(spoken.status, 0) << spoken.err;
  EXPECT_EQ(
      spoken.err,
      "lipsync: warning: espeak-ng read 'hello' by the rules of another language (en), not those of voice 'ru'\n");
  fs::remove_all(dir);
}

TEST_F(SpeakTest, AFullServerRefusesWithResourceExhausted) {
  ServerConfig config;
  config.max_streams = 1;
  start(config);
  Producer producer(*stub_, {});
  const SpeakStream refused = speak_raw(*stub_, speak_request("Hello."));
  EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED) << refused.status.error_message();
  EXPECT_THAT(refused.status.error_message(), HasSubstr("--max-streams"));
}

TEST_F(SpeakTest, CallsSpeakingOrWaitingForTheSynthesiserAtTheDrainDeadlineGetAborted) {
  ServerConfig config;
  config.metrics_listen = "127.0.0.1:0";
  start(config);
  // The speech thread speaks one text at a time, and each of these (4,000 bytes read slowly: five
  // minutes of speech) takes espeak-ng about a second: at a 200 ms deadline the first call is
  // still speaking and the others still wait for the synthesiser.
  v1::SpeakRequest request;
  while (request.text().size() < 4000)
    request.mutable_text()->append("Papa parked the car by the ferry, and Bob waved. ");
  request.set_words_per_minute(80);
  constexpr int kCalls = 3;
  std::vector<std::future<SpeakStream>> calls;
  for (int i = 0; i < kCalls; ++i) {
    v1::SpeakRequest named = request;
    named.mutable_settings()->set_session("spoken-" + std::to_string(i));
    calls.push_back(std::async(std::launch::async, [this, named] { return speak_raw(*stub_, named); }));
  }
  // Each call opens its session before it queues for the synthesiser.
  const auto live_sessions = [&] {
    const Exposition metrics = parse_exposition(http_get(server_->metrics_address(), "/metrics"));
    return metrics.at(R"(lipsyncd_sessions{state="live",tenant=""})");
  };
  ASSERT_TRUE(eventually([&] { return live_sessions() == kCalls; }));
  server_->shutdown(std::chrono::milliseconds(200));
  for (int i = 0; i < kCalls; ++i) {
    const SpeakStream stream = calls[static_cast<std::size_t>(i)].get();
    EXPECT_EQ(stream.status.error_code(), grpc::StatusCode::ABORTED) << i << ": " << stream.status.error_message();
    EXPECT_THAT(stream.status.error_message(), HasSubstr("--drain-deadline-ms=200")) << i;
    EXPECT_TRUE(stream.messages.empty()) << i << ": nothing is sent once the call is aborted";
  }
}

TEST_F(SpeakTest, LipsyncSpeakWritesWhatLipsyncSayWrites) {
  namespace fs = std::filesystem;
  const fs::path dir = testing::make_temp_dir("lipsync-speak-test-");
  const auto run = [&](std::vector<std::string> args) {
    args.insert(args.begin(), LIPSYNC_CLI_BINARY);
    return testing::run_program(std::move(args), dir, dir);
  };
  const std::string text = kSentences[1];
  const auto said = run({"say", text, "-o", "said.json", "--wav", "said.wav"});
  ASSERT_EQ(said.status, 0) << said.err;
  const auto spoken = run({"speak", text, "--server", server_->address(), "-o", "spoken.json", "--wav", "spoken.wav"});
  ASSERT_EQ(spoken.status, 0) << spoken.err;
  const std::string said_wav = testing::read_text(dir / "said.wav");
  EXPECT_GT(said_wav.size(), 44U);
  EXPECT_TRUE(testing::read_text(dir / "spoken.wav") == said_wav) << "the WAV files differ";
  const std::string said_track = testing::read_text(dir / "said.json");
  EXPECT_GT(said_track.size(), 100U);
  EXPECT_TRUE(testing::read_text(dir / "spoken.json") == said_track) << "the track files differ";

  const auto refused = run({"speak", "Hello.", "--server", server_->address(), "--voice", "no-such-voice"});
  EXPECT_EQ(refused.status, 1);
  EXPECT_THAT(refused.err, HasSubstr("INVALID_ARGUMENT: voice:"));
  EXPECT_EQ(run({"speak", "--server", server_->address()}).status, 2);  // no TEXT
  const auto help = run({"speak", "--help"});
  EXPECT_EQ(help.status, 0);
  EXPECT_THAT(help.out, HasSubstr("--server ADDR"));
  EXPECT_THAT(help.out, HasSubstr("--wav FILE"));
  fs::remove_all(dir);
}

TEST_F(SpeakTest, LipsyncSpeakAnchorsItsSessionAPlayoutDelayAheadAndPublishesVisemesWhenAsked) {
  namespace fs = std::filesystem;
  const fs::path dir = testing::make_temp_dir("lipsync-speak-test-");
  const auto run = [&](std::vector<std::string> args) {
    args.insert(args.begin(), LIPSYNC_CLI_BINARY);
    args.insert(args.end(), {"--server", server_->address(), "-o", "/dev/null"});
    return testing::run_program(std::move(args), dir, dir);
  };
  const auto unix_now_us = [] {
    return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
        .count();
  };
  /// The session's anchor less the wall clock when `lipsync speak` ran: within [before, after].
  const auto check_anchor = [&](const std::vector<std::string>& args, const std::string& session,
                                std::int64_t delay_us) {
    const std::int64_t before = unix_now_us();
    const auto spoken = run(args);
    const std::int64_t after = unix_now_us();
    EXPECT_EQ(spoken.status, 0) << spoken.err;
    const Received received = subscribe_all(*stub_, session);
    EXPECT_TRUE(received.status.ok()) << received.status.error_message();
    EXPECT_TRUE(received.header.has_value());
    if (!received.header) return std::vector<std::string>{};
    const v1::MediaClockAnchor& anchor = received.header->media_clock();
    EXPECT_EQ(anchor.clock(), "unix");
    EXPECT_GE(anchor.utterance_zero_us(), before + delay_us);
    EXPECT_LE(anchor.utterance_zero_us(), after + delay_us);
    return std::vector<std::string>(received.header->viseme_names().begin(), received.header->viseme_names().end());
  };
  EXPECT_THAT(check_anchor({"speak", kSentences[0], "--session", "ahead", "--visemes", "oculus"}, "ahead", 1'000'000),
              ::testing::Contains("PP"));
  EXPECT_THAT(
      check_anchor({"speak", kSentences[0], "--session", "sooner", "--playout-delay", "250"}, "sooner", 250'000),
      ::testing::IsEmpty());

  const auto without_session = run({"speak", "Hello.", "--visemes", "oculus"});
  EXPECT_EQ(without_session.status, 2);
  EXPECT_THAT(without_session.err, HasSubstr("--visemes needs --session"));
  const auto unknown = run({"speak", "Hello.", "--session", "x", "--visemes", "klingon"});
  EXPECT_EQ(unknown.status, 2);
  EXPECT_THAT(unknown.err,
              HasSubstr("--visemes: unknown vocabulary 'klingon' (choose oculus, azure, polly or rhubarb)"));
  const auto too_late = run({"speak", "Hello.", "--playout-delay", "600001"});
  EXPECT_EQ(too_late.status, 2);
  EXPECT_THAT(too_late.err, HasSubstr("--playout-delay"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lipsync::server
