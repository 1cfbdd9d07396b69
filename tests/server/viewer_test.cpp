// The browser viewer's HTTP port without a browser: a real lipsyncd (in-process, --http-listen on
// 127.0.0.1:0) and real clients over real sockets (Beast's HTTP and WebSocket clients, gRPC).
// A WebSocket follower receives exactly the messages a gRPC Subscribe receives, byte for byte; bad
// requests get a status or close reason that names what was wrong; the page, its scripts and its
// face are served; a quick try animates pasted text as a session equal to a Render of it; a Speak
// session's voice is served as a WAV (/audio), to the callers that may follow the session.
// The page itself, in Chromium, is tests/server/viewer_browser_test.py.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <future>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../support/child_process.hpp"
#include "../support/server_harness.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/speech/audio.hpp"
#include "transport/tenants.hpp"

namespace lipsync::server {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using tcp = boost::asio::ip::tcp;
using namespace harness;

std::string read_fixture(const std::string& relative) {
  std::ifstream file(std::string(LIPSYNC_TEST_DATA_DIR) + "/" + relative, std::ios::binary);
  std::ostringstream text;
  text << file.rdbuf();
  return text.str();
}

/// flite's own timings of "Papa bought five more big maps." (radio phone set).
std::vector<LabeledInterval> flite_papa() {
  const std::string text = read_fixture("closures/flite_1.psdur");
  return parse_utterance(text, InputFormat::flite, "flite_1.psdur").intervals;
}

v1::AnimationSettings papa_settings(const std::string& session) {
  v1::AnimationSettings settings;
  settings.set_phone_set("radio");
  settings.set_session(session);
  settings.mutable_outputs()->mutable_visemes()->set_enabled(true);
  settings.mutable_media_clock()->set_clock("unix");
  settings.mutable_media_clock()->set_utterance_zero_us(1'700'000'000'000'000);
  return settings;
}

struct HttpReply {
  unsigned status = 0;
  std::string content_type;
  std::string body;
};

/// What a WebSocket follower received: its binary messages, text messages and the close.
struct WebSocketReply {
  std::vector<std::string> binary;
  std::vector<std::string> text;
  websocket::close_reason close;
};

class ViewerTest : public LiveServerTest {
 protected:
  void SetUp() override {
    ServerConfig config;
    config.session_retention_ms = 60'000;
    start_viewer(config);
  }

  /// Starts lipsyncd with `config` and its viewer on a free port.
  void start_viewer(ServerConfig config) {
    config.http_listen = "127.0.0.1:0";
    start(config);
    const std::string address = server_->http_address();
    http_host_ = address.substr(0, address.rfind(':'));
    http_port_ = address.substr(address.rfind(':') + 1);
  }

  tcp::socket connect_http() {
    tcp::resolver resolver(io_);
    tcp::socket socket(io_);
    boost::asio::connect(socket, resolver.resolve(http_host_, http_port_));
    return socket;
  }

  HttpReply request(http::verb verb, const std::string& target, const std::string& body = "") {
    tcp::socket socket = connect_http();
    http::request<http::string_body> req(verb, target, 11);
    req.set(http::field::host, http_host_);
    req.body() = body;
    req.prepare_payload();
    http::write(socket, req);
    beast::flat_buffer buffer;
    http::response<http::string_body> response;
    http::read(socket, buffer, response);
    return {response.result_int(), std::string(response[http::field::content_type]), response.body()};
  }

  /// Reads until the server closes; `first_binary`, if given, is set when the first binary message arrives.
  WebSocketReply follow(const std::string& target, std::promise<void>* first_binary = nullptr) {
    websocket::stream<tcp::socket> ws(connect_http());
    ws.handshake(http_host_, target);
    WebSocketReply reply;
    for (;;) {
      beast::flat_buffer buffer;
      beast::error_code error;
      ws.read(buffer, error);
      if (error == websocket::error::closed) break;
      if (error) throw beast::system_error(error);
      (ws.got_binary() ? reply.binary : reply.text).push_back(beast::buffers_to_string(buffer.data()));
      if (first_binary && ws.got_binary() && reply.binary.size() == 1) first_binary->set_value();
    }
    reply.close = ws.reason();
    return reply;
  }

  /// An Animate stream that has opened session `name` (its header is read) and sent no phoneme yet.
  std::unique_ptr<grpc::ClientReaderWriter<v1::AnimateRequest, v1::TrackMessage>> open_session(
      grpc::ClientContext& context, const std::string& name) {
    set_deadline(context);
    auto producer = stub_->Animate(&context);
    EXPECT_TRUE(producer->Write(settings_request(papa_settings(name))));
    v1::TrackMessage header;
    EXPECT_TRUE(producer->Read(&header));
    return producer;
  }

  /// A finished session named `session`: flite's "Papa ..." through Animate, in chunks of 3.
  void produce_papa(const std::string& session) {
    const Received produced = animate(*stub_, whole(papa_settings(session), flite_papa(), 3));
    ASSERT_TRUE(produced.status.ok()) << produced.status.error_message();
  }

  /// `authorization`, if not empty, is sent as the Authorization header.
  HttpReply request(http::verb verb, const std::string& target, const std::string& body,
                    const std::string& authorization) {
    tcp::socket socket = connect_http();
    http::request<http::string_body> req(verb, target, 11);
    req.set(http::field::host, http_host_);
    if (!authorization.empty()) req.set(http::field::authorization, authorization);
    req.body() = body;
    req.prepare_payload();
    http::write(socket, req);
    beast::flat_buffer buffer;
    http::response<http::string_body> response;
    http::read(socket, buffer, response);
    return {response.result_int(), std::string(response[http::field::content_type]), response.body()};
  }

  /// A Speak call of `text` into `session`: the WAV of the audio it sent (what /audio must serve).
  std::string speak_wav(const std::string& text, const std::string& session, const std::string& key = "") {
    grpc::ClientContext context;
    set_deadline(context);
    if (!key.empty()) context.AddMetadata("authorization", "Bearer " + key);
    v1::SpeakRequest request;
    request.set_text(text);
    request.mutable_settings()->set_session(session);
    auto reader = stub_->Speak(&context, request);
    speech::PcmAudio audio;
    v1::SpeakResponse message;
    while (reader->Read(&message)) {
      if (message.has_header()) audio.sample_rate_hz = static_cast<int>(message.header().sample_rate_hz());
      if (!message.has_audio()) continue;
      const std::string& pcm = message.audio().pcm();
      for (std::size_t i = 0; i + 1 < pcm.size(); i += 2) {
        audio.samples.push_back(
            static_cast<std::int16_t>(static_cast<std::uint8_t>(pcm[i]) | static_cast<std::uint8_t>(pcm[i + 1]) << 8));
      }
    }
    const grpc::Status status = reader->Finish();
    EXPECT_TRUE(status.ok()) << status.error_message();
    std::ostringstream wav;
    speech::write_wav(wav, audio);
    return wav.str();
  }

  boost::asio::io_context io_;
  std::string http_host_, http_port_;
};

TEST_F(ViewerTest, WebsocketFollowerReceivesTheSameMessagesAsAGrpcSubscriber) {
  produce_papa("papa");
  const SubscribedBytes subscribed = subscribe_bytes(*stub_, "papa");
  ASSERT_TRUE(subscribed.status.ok()) << subscribed.status.error_message();
  const std::vector<std::string>& expected = subscribed.messages;

  const WebSocketReply reply = follow("/ws?session=papa");
  EXPECT_EQ(reply.close.code, websocket::close_code::normal);
  EXPECT_TRUE(reply.text.empty());
  ASSERT_GE(reply.binary.size(), 3u);  // header, batches, summary
  EXPECT_EQ(reply.binary, expected);
  v1::TrackMessage first, last;
  ASSERT_TRUE(first.ParseFromString(reply.binary.front()));
  ASSERT_TRUE(last.ParseFromString(reply.binary.back()));
  ASSERT_TRUE(first.has_header());
  EXPECT_EQ(first.header().session(), "papa");
  EXPECT_EQ(first.header().media_clock().clock(), "unix");
  EXPECT_EQ(first.header().media_clock().utterance_zero_us(), 1'700'000'000'000'000);
  EXPECT_THAT(first.header().viseme_names(), ::testing::Contains("PP"));
  EXPECT_TRUE(last.has_summary());
}

TEST_F(ViewerTest, WebsocketFollowerOfALiveSessionGetsFramesAsTheyAreProduced) {
  grpc::ClientContext context;
  auto producer = open_session(context, "live");
  WebSocketReply reply;
  std::thread follower([&] { reply = follow("/ws?session=live&start=beginning"); });
  for (auto& chunk : chunked(flite_papa(), 4)) ASSERT_TRUE(producer->Write(chunk));
  ASSERT_TRUE(producer->Write(end_request()));
  producer->WritesDone();
  v1::TrackMessage message;
  while (producer->Read(&message)) {
  }
  ASSERT_TRUE(producer->Finish().ok());
  follower.join();

  Received followed;
  for (const std::string& bytes : reply.binary) {
    v1::TrackMessage received;
    ASSERT_TRUE(received.ParseFromString(bytes));
    take(followed, received);
  }
  const Received rendered = subscribe_all(*stub_, "live");
  ASSERT_TRUE(followed.header && followed.summary);
  EXPECT_EQ(followed.frames.t_us, rendered.frames.t_us);
  EXPECT_EQ(followed.frames.arkit, rendered.frames.arkit);
  EXPECT_EQ(reply.close.code, websocket::close_code::normal);
}

TEST_F(ViewerTest, UnknownSessionClosesTheWebsocketWithNotFoundNamingTheSession) {
  const WebSocketReply reply = follow("/ws?session=nobody-here");
  EXPECT_TRUE(reply.binary.empty());
  ASSERT_EQ(reply.text.size(), 1u);
  const auto error = nlohmann::json::parse(reply.text.front());
  EXPECT_EQ(error["code"], "NOT_FOUND");
  EXPECT_THAT(error["message"].get<std::string>(), ::testing::HasSubstr("'nobody-here'"));
  EXPECT_EQ(reply.close.code, 4000 + grpc::StatusCode::NOT_FOUND);
  EXPECT_THAT(std::string(reply.close.reason.c_str()), ::testing::HasSubstr("nobody-here"));
  EXPECT_LE(reply.close.reason.size(), 123u);
}

TEST_F(ViewerTest, WebsocketWithoutASessionOrWithABadStartOrWaitIsInvalidArgument) {
  WebSocketReply reply = follow("/ws");
  EXPECT_EQ(reply.close.code, 4000 + grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(std::string(reply.close.reason.c_str()), ::testing::HasSubstr("session=NAME"));
  reply = follow("/ws?session=x&start=yesterday");
  EXPECT_EQ(reply.close.code, 4000 + grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(std::string(reply.close.reason.c_str()), ::testing::HasSubstr("'yesterday'"));
  for (const std::string wait : {"3601", "-1", "2s", ""}) {
    reply = follow("/ws?session=x&wait_s=" + wait);
    EXPECT_EQ(reply.close.code, 4000 + grpc::StatusCode::INVALID_ARGUMENT) << wait;
    EXPECT_THAT(std::string(reply.close.reason.c_str()), ::testing::HasSubstr("wait_s: expected whole seconds"))
        << wait;
  }
}

TEST_F(ViewerTest, AFollowerAskingToWaitIsToldSoAndGetsTheSessionOnceItStarts) {
  WebSocketReply reply;
  std::thread follower([&] { reply = follow("/ws?session=later&wait_s=30"); });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the follower waits
  produce_papa("later");
  follower.join();
  const SubscribedBytes subscribed = subscribe_bytes(*stub_, "later");
  ASSERT_TRUE(subscribed.status.ok()) << subscribed.status.error_message();
  ASSERT_EQ(reply.text.size(), 1u);
  EXPECT_EQ(nlohmann::json::parse(reply.text.front()), nlohmann::json({{"waiting", "later"}, {"wait_s", 30}}));
  EXPECT_EQ(reply.binary, subscribed.messages);
  EXPECT_EQ(reply.close.code, websocket::close_code::normal);
}

TEST_F(ViewerTest, AFollowerThatWaitsInVainGetsNotFoundSayingHowLongItWaited) {
  const auto started = std::chrono::steady_clock::now();
  const WebSocketReply reply = follow("/ws?session=never&wait_s=1");
  EXPECT_GE(std::chrono::steady_clock::now() - started, std::chrono::seconds(1));
  EXPECT_TRUE(reply.binary.empty());
  ASSERT_EQ(reply.text.size(), 2u);
  EXPECT_EQ(nlohmann::json::parse(reply.text[0])["waiting"], "never");
  const auto error = nlohmann::json::parse(reply.text[1]);
  EXPECT_EQ(error["code"], "NOT_FOUND");
  EXPECT_THAT(error["message"].get<std::string>(), ::testing::HasSubstr("session 'never' did not start within 1 s"));
  EXPECT_EQ(reply.close.code, 4000 + grpc::StatusCode::NOT_FOUND);
}

TEST_F(ViewerTest, AFollowerThatLeavesWhileWaitingIsAnsweredAtOnce) {
  websocket::stream<tcp::socket> ws(connect_http());
  ws.handshake(http_host_, "/ws?session=never&wait_s=30");
  beast::flat_buffer buffer;
  ws.read(buffer);  // {"waiting": ...}
  const auto started = std::chrono::steady_clock::now();
  beast::error_code error;
  ws.close(websocket::close_code::normal, error);  // answered by lipsyncd's close
  EXPECT_FALSE(error) << error.message();
  EXPECT_LT(std::chrono::steady_clock::now() - started, std::chrono::seconds(2));
}

TEST_F(ViewerTest, ShutdownEndsAFollowerWaitingForItsSessionToStartWithGoingAway) {
  WebSocketReply reply;
  std::thread follower([&] { reply = follow("/ws?session=never&wait_s=30"); });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  server_->shutdown(std::chrono::milliseconds(0));
  follower.join();
  ASSERT_EQ(reply.text.size(), 1u);  // {"waiting": ...}
  EXPECT_EQ(reply.close.code, websocket::close_code::going_away);
}

TEST_F(ViewerTest, UnknownPathIs404NamingItAndWsWithoutUpgradeIs426) {
  const HttpReply missing = request(http::verb::get, "/no/such/thing");
  EXPECT_EQ(missing.status, 404u);
  EXPECT_THAT(missing.body, ::testing::HasSubstr("/no/such/thing"));
  EXPECT_EQ(request(http::verb::get, "/ws?session=x").status, 426u);
  EXPECT_EQ(request(http::verb::get, "/listen?session=x&rate=16000").status, 426u);
  EXPECT_EQ(request(http::verb::post, "/viewer.js").status, 405u);
  EXPECT_EQ(request(http::verb::get, "/sessions").status, 405u);
}

TEST_F(ViewerTest, PageScriptsAndFaceAreServedFromTheBinary) {
  const HttpReply page = request(http::verb::get, "/view?session=demo&audio=speech.wav");
  EXPECT_EQ(page.status, 200u);
  EXPECT_THAT(page.content_type, ::testing::StartsWith("text/html"));
  for (const char* id : {"id=\"frame-time\"", "id=\"viseme\"", "id=\"drift\"", "id=\"latency\"", "id=\"talk\"",
                         "/viewer.js", "/face_drawing.js", "/audio_steering.js", "/live_voice.js"}) {
    EXPECT_THAT(page.body, ::testing::HasSubstr(id));
  }
  EXPECT_EQ(request(http::verb::get, "/").body, page.body);
  EXPECT_THAT(request(http::verb::get, "/viewer.js").body, ::testing::HasSubstr("window.lipsyncViewer"));
  EXPECT_THAT(request(http::verb::get, "/track_decoder.js").body, ::testing::HasSubstr("decodeTrackMessage"));
  EXPECT_THAT(request(http::verb::get, "/face_drawing.js").body, ::testing::HasSubstr("function draw()"));
  EXPECT_THAT(request(http::verb::get, "/audio_steering.js").body, ::testing::HasSubstr("function steer("));
  EXPECT_THAT(request(http::verb::get, "/live_voice.js").body, ::testing::HasSubstr("/listen?"));
  const HttpReply worklet = request(http::verb::get, "/capture_worklet.js");
  EXPECT_THAT(worklet.content_type, ::testing::StartsWith("text/javascript"));
  EXPECT_THAT(worklet.body, ::testing::HasSubstr("registerProcessor(\"lipsync-capture\""));
  const HttpReply face = request(http::verb::get, "/face.json");
  EXPECT_EQ(face.content_type, "application/json");
  const auto json = nlohmann::json::parse(face.body);
  EXPECT_EQ(json["format"], "lipsync-viewer-face 1");
  EXPECT_EQ(json["rest_um"].size(), 3 * json["vertex_count"].get<std::size_t>());
  EXPECT_FALSE(json["blendshapes"].empty());
}

TEST_F(ViewerTest, QuickTryAnimatesPastedTextAsASessionEqualToARender) {
  const std::string text = read_fixture("closures/flite_1.psdur");
  const HttpReply reply = request(http::verb::post, "/sessions?session=pasted&fps=60", text);
  ASSERT_EQ(reply.status, 200u) << reply.body;
  const auto answer = nlohmann::json::parse(reply.body);
  EXPECT_EQ(answer["session"], "pasted");
  EXPECT_EQ(answer["phonemes"], flite_papa().size());
  EXPECT_EQ(answer["view"], "/view?session=pasted");

  const Received followed = subscribe_all(*stub_, "pasted");
  ASSERT_TRUE(followed.status.ok()) << followed.status.error_message();
  EXPECT_EQ(followed.header->media_clock().clock(), "unix");
  EXPECT_EQ(followed.header->media_clock().utterance_zero_us(), answer["utterance_zero_us"].get<std::int64_t>());
  EXPECT_EQ(followed.header->fps(), 60u);
  EXPECT_EQ(answer["frames"], followed.frames.t_us.size());

  grpc::ClientContext context;
  set_deadline(context);
  v1::RenderRequest render;
  *render.mutable_settings() = papa_settings("");
  render.mutable_settings()->set_fps(60);
  for (const auto& interval : flite_papa()) *render.add_phonemes() = to_proto(interval);
  v1::RenderResponse rendered;
  ASSERT_TRUE(stub_->Render(&context, render, &rendered).ok());
  EXPECT_THAT(followed.frames.t_us, ::testing::ElementsAreArray(rendered.frames().t_us()));
  EXPECT_THAT(followed.frames.values, ::testing::ElementsAreArray(rendered.frames().values()));
}

TEST_F(ViewerTest, QuickTryReportsBadTextBadParametersAndTakenNames) {
  HttpReply reply = request(http::verb::post, "/sessions?session=bad", "pau:0.1 p:0.05 aa:0.3\n");
  EXPECT_EQ(reply.status, 400u);
  EXPECT_THAT(nlohmann::json::parse(reply.body)["message"].get<std::string>(), ::testing::StartsWith("pasted text:"));
  reply = request(http::verb::post, "/sessions?fps=1000", "pau:0.1 p:0.2\n");
  EXPECT_EQ(reply.status, 400u);
  EXPECT_THAT(reply.body, ::testing::HasSubstr("fps: expected an integer from 1 to 240, got '1000'"));
  reply = request(http::verb::post, "/sessions?phone_set=klingon", "pau:0.1 p:0.2\n");
  EXPECT_EQ(reply.status, 400u);
  EXPECT_THAT(reply.body, ::testing::HasSubstr("klingon"));

  // A live producer holds the name: ALREADY_EXISTS is 409.
  grpc::ClientContext context;
  auto producer = open_session(context, "taken");
  reply = request(http::verb::post, "/sessions?session=taken", "pau:0.1 p:0.2\n");
  EXPECT_EQ(reply.status, 409u);
  EXPECT_EQ(nlohmann::json::parse(reply.body)["code"], "ALREADY_EXISTS");
  context.TryCancel();
}

TEST_F(ViewerTest, AudioServesASpeakSessionsOwnVoiceAsTheWavSpeakSent) {
  const std::string expected = speak_wav("Papa parked the car.", "spoken");
  ASSERT_GT(expected.size(), 44u + 2 * 8000);  // a header and over a quarter of a second at 16 kHz or more
  const HttpReply reply = request(http::verb::get, "/audio?session=spoken");
  ASSERT_EQ(reply.status, 200u) << reply.body;
  EXPECT_EQ(reply.content_type, "audio/wav");
  EXPECT_EQ(reply.body, expected);  // byte for byte: the samples Speak streamed, as a WAV
}

TEST_F(ViewerTest, AudioIs404NamingASessionWithoutAudioOrUnknownAnd400WithoutAName) {
  produce_papa("animated");
  HttpReply reply = request(http::verb::get, "/audio?session=animated");
  EXPECT_EQ(reply.status, 404u);
  EXPECT_EQ(reply.content_type, "application/json");
  auto error = nlohmann::json::parse(reply.body);
  EXPECT_EQ(error["code"], "NOT_FOUND");
  EXPECT_THAT(error["message"].get<std::string>(), ::testing::HasSubstr("session 'animated' has no audio"));
  reply = request(http::verb::get, "/audio?session=nobody-here");
  EXPECT_EQ(reply.status, 404u);
  EXPECT_THAT(nlohmann::json::parse(reply.body)["message"].get<std::string>(), ::testing::HasSubstr("'nobody-here'"));
  reply = request(http::verb::get, "/audio");
  EXPECT_EQ(reply.status, 400u);
  EXPECT_THAT(reply.body, ::testing::HasSubstr("/audio?session=NAME"));
  EXPECT_EQ(request(http::verb::post, "/audio?session=animated").status, 405u);
}

/// "Papa ..." with `wav` attached in pieces of `piece_bytes` (AudioAttachment) between the settings
/// and the phonemes; `session` may be empty (a private stream).
std::vector<v1::AnimateRequest> papa_with_audio(const std::string& session, const std::string& wav,
                                                std::size_t piece_bytes) {
  std::vector<v1::AnimateRequest> requests = whole(papa_settings(session), flite_papa(), 3);
  std::vector<v1::AnimateRequest> pieces;
  for (std::size_t offset = 0; offset < wav.size(); offset += piece_bytes) {
    pieces.emplace_back().mutable_audio()->set_wav(wav.substr(offset, piece_bytes));
  }
  requests.insert(requests.begin() + 1, pieces.begin(), pieces.end());
  return requests;
}

/// A 44.1 kHz stereo 16-bit WAV of `seconds` (a file as a TTS front-end might write it, not lipsyncd's own
/// 16-bit mono): a canonical header and a ramp of samples.
std::string stereo_wav(double seconds) {
  const std::uint32_t rate = 44'100, frames = static_cast<std::uint32_t>(seconds * rate), data = frames * 4;
  std::string wav = "RIFF....WAVEfmt ";
  const auto put = [&wav](std::uint32_t value, int bytes) {
    for (int i = 0; i < bytes; ++i) wav.push_back(static_cast<char>(value >> (8 * i) & 0xFF));
  };
  put(16, 4), put(1, 2), put(2, 2), put(rate, 4), put(rate * 4, 4), put(4, 2), put(16, 2);
  wav += "data";
  put(data, 4);
  for (std::uint32_t i = 0; i < frames * 2; ++i) put(i * 37 % 65'536, 2);
  const std::uint32_t riff = static_cast<std::uint32_t>(wav.size() - 8);
  for (int i = 0; i < 4; ++i) wav[4 + i] = static_cast<char>(riff >> (8 * i) & 0xFF);
  return wav;
}

TEST_F(ViewerTest, AudioAttachedByTheProducerIsServedByteForByteAsTheFileItSent) {
  const std::string wav = stereo_wav(2.5);  // 441 KB: three pieces of 200 KB
  const Received produced = animate(*stub_, papa_with_audio("papa-with-sound", wav, 200'000));
  ASSERT_TRUE(produced.status.ok()) << produced.status.error_message();
  const Received silent = animate(*stub_, whole(papa_settings("papa-without-sound"), flite_papa(), 3));
  EXPECT_EQ(produced.frames.t_us, silent.frames.t_us);  // the frames are those of the phonemes alone
  EXPECT_EQ(produced.frames.values, silent.frames.values);
  const HttpReply reply = request(http::verb::get, "/audio?session=papa-with-sound");
  ASSERT_EQ(reply.status, 200u) << reply.body;
  EXPECT_EQ(reply.content_type, "audio/wav");
  EXPECT_EQ(reply.body.size(), wav.size());
  EXPECT_TRUE(reply.body == wav) << "the served WAV differs from the attached file";
}

// A server whose sessions may keep 1 MB of sound together, for 300 ms after they end.
class SessionAudioBudgetTest : public ViewerTest {
 protected:
  void SetUp() override {
    ServerConfig config;
    config.session_retention_ms = 300;
    config.max_session_audio_bytes = 1'000'000;
    start_viewer(config);
  }
};

TEST_F(SessionAudioBudgetTest, SessionsKeepTheirSoundWithinTheServersBudgetAndGiveItBackWhenTheyExpire) {
  const std::string wav = stereo_wav(2.5);  // 441 KB: two fit in 1 MB, a third does not
  for (const std::string name : {"first-voice", "second-voice"}) {
    const Received produced = animate(*stub_, papa_with_audio(name, wav, 200'000));
    ASSERT_TRUE(produced.status.ok()) << name << ": " << produced.status.error_message();
  }
  const Received refused = animate(*stub_, papa_with_audio("third-voice", wav, 200'000));
  EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.status.error_message(),
              ::testing::StartsWith("audio.wav: the sessions' audio would be over the server's 1000000 bytes "
                                    "(--max-session-audio-bytes)"));
  EXPECT_TRUE(refused.frames.t_us.empty());
  EXPECT_EQ(request(http::verb::get, "/audio?session=first-voice").body, wav);  // the others keep theirs
  // Once the two sessions have expired, their sound is given back and a new session keeps its own.
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  Received again;
  for (int attempt = 0; attempt < 20; ++attempt) {
    again = animate(*stub_, papa_with_audio("fourth-voice-" + std::to_string(attempt), wav, 200'000));
    if (again.status.ok()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(again.status.ok()) << again.status.error_message();
}

TEST_F(ViewerTest, AttachedAudioThatIsNotAWavIsInvalidArgumentNamingAudioWav) {
  const Received produced = animate(*stub_, papa_with_audio("papa-not-wav", "ID3\x04 an mp3, not a WAV", 100));
  EXPECT_EQ(produced.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(produced.status.error_message(), ::testing::StartsWith("audio.wav: not a WAV file"));
  EXPECT_TRUE(produced.frames.t_us.empty());  // refused before any frame
  EXPECT_EQ(request(http::verb::get, "/audio?session=papa-not-wav").status, 404u);
}

TEST_F(ViewerTest, AttachedAudioOver32MibIsResourceExhaustedNamingAudioWav) {
  const std::string piece(3 * 1024 * 1024, '\0');  // within the 4 MiB message limit; 11 of them are 33 MiB
  // Sent a piece every 50 ms, so that lipsyncd reads each before the next: pieces that wait for it
  // beyond the transport's memory quota (about 20 MB on an idle server) end the stream first
  // (RST_STREAM ENHANCE_YOUR_CALM, RESOURCE_EXHAUSTED without lipsyncd's message; CI saw it once, on
  // a busy host, when the pieces went out at once). Should that still happen, the call is made again:
  // the attached-audio limit is what this test is for.
  Received produced;
  for (int attempt = 0; attempt < 3; ++attempt) {
    std::vector<v1::AnimateRequest> requests{
        settings_request(papa_settings("papa-too-loud-" + std::to_string(attempt)))};
    for (int i = 0; i < 11; ++i) requests.emplace_back().mutable_audio()->set_wav(piece);
    requests.push_back(end_request());
    produced = animate(*stub_, requests, std::chrono::milliseconds(50));
    if (produced.status.error_message().rfind("Received RST_STREAM", 0) != 0) break;
    std::printf("attempt %d: the transport's quota ended the stream first (%s)\n", attempt,
                produced.status.error_message().c_str());
  }
  EXPECT_EQ(produced.status.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(produced.status.error_message(), ::testing::StartsWith("audio.wav: the attached audio is over 33554432"));
}

TEST_F(ViewerTest, AudioWithoutASessionOrAfterThePhonemesIsInvalidArgumentNamingAudio) {
  Received produced = animate(*stub_, papa_with_audio("", stereo_wav(0.1), 100'000));
  EXPECT_EQ(produced.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(produced.status.error_message(), ::testing::StartsWith("audio: attached to a stream without"));
  std::vector<v1::AnimateRequest> late = whole(papa_settings("papa-late-sound"), flite_papa(), 3);
  late.insert(late.end() - 1, v1::AnimateRequest());
  late[late.size() - 2].mutable_audio()->set_wav(stereo_wav(0.1));
  produced = animate(*stub_, late);
  EXPECT_EQ(produced.status.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_THAT(produced.status.error_message(), ::testing::StartsWith("audio: sent after the first phonemes"));
}

TEST_F(ViewerTest, QuickTryWithSpeakSpeaksTheTextIntoASessionThatCarriesItsVoice) {
  const HttpReply reply = request(http::verb::post, "/sessions?session=said&speak=1", "Papa parked the car.");
  ASSERT_EQ(reply.status, 200u) << reply.body;
  const auto answer = nlohmann::json::parse(reply.body);
  EXPECT_EQ(answer["session"], "said");
  EXPECT_EQ(answer["audio"], "/audio?session=said");
  EXPECT_GT(answer["audio_duration_us"].get<std::int64_t>(), 500'000);
  const Received followed = subscribe_all(*stub_, "said");
  ASSERT_TRUE(followed.status.ok()) << followed.status.error_message();
  EXPECT_EQ(followed.header->media_clock().clock(), "unix");
  EXPECT_EQ(followed.header->media_clock().utterance_zero_us(), answer["utterance_zero_us"].get<std::int64_t>());
  EXPECT_EQ(answer["frames"], followed.frames.t_us.size());
  const HttpReply audio = request(http::verb::get, "/audio?session=said");
  ASSERT_EQ(audio.status, 200u);
  // 16-bit mono: a 44-byte header (the rate at byte 24, little-endian) and the audio's samples.
  ASSERT_GT(audio.body.size(), 44u);
  std::uint32_t rate = 0;
  for (int i = 3; i >= 0; --i) rate = rate << 8 | static_cast<std::uint8_t>(audio.body[24 + i]);
  const auto samples = static_cast<double>(audio.body.size() - 44) / 2;
  EXPECT_NEAR(samples * 1e6 / rate, answer["audio_duration_us"].get<double>(), 100.0);

  HttpReply bad = request(http::verb::post, "/sessions?speak=2", "Papa.");
  EXPECT_EQ(bad.status, 400u);
  EXPECT_THAT(bad.body, ::testing::HasSubstr("speak: expected 1"));
  bad = request(http::verb::post, "/sessions?speak=1", "   ");
  EXPECT_EQ(bad.status, 400u);
  EXPECT_THAT(bad.body, ::testing::HasSubstr("text: empty"));
}

// With --api-keys, /audio is a Subscribe's business: a key that may Subscribe, and only its tenant's sessions.
class ViewerWithKeysTest : public ViewerTest {
 protected:
  void SetUp() override {
    lipsync::testing::write_text(key_file_, R"({"tenants": {"a": {}, "b": {}}, "keys": [)"
                                            R"({"tenant": "a", "sha256": ")" +
                                                sha256_hex("key-a") +
                                                R"("},)"
                                                R"({"tenant": "a", "calls": ["Animate"], "sha256": ")" +
                                                sha256_hex("key-a-animate") +
                                                R"("},)"
                                                R"({"tenant": "b", "sha256": ")" +
                                                sha256_hex("key-b") + R"("}]})");
    ServerConfig config;
    config.http_listen = "127.0.0.1:0";
    config.api_keys = key_file_.string();
    start(config);
    const std::string address = server_->http_address();
    http_host_ = address.substr(0, address.rfind(':'));
    http_port_ = address.substr(address.rfind(':') + 1);
  }
  std::filesystem::path key_file_ = lipsync::testing::make_temp_dir("lipsync-viewer-keys-") / "keys.json";
};

TEST_F(ViewerWithKeysTest, AudioNeedsAKeyThatMaySubscribeAndFindsOnlyItsTenantsSessions) {
  const std::string expected = speak_wav("Bob bought maps.", "spoken", "key-a");
  EXPECT_EQ(request(http::verb::get, "/audio?session=spoken").status, 401u);
  EXPECT_EQ(request(http::verb::get, "/audio?session=spoken&key=key-a-animate").status, 403u);
  EXPECT_EQ(request(http::verb::get, "/audio?session=spoken&key=key-b").status, 404u);  // another tenant's
  HttpReply reply = request(http::verb::get, "/audio?session=spoken&key=key-a");
  EXPECT_EQ(reply.status, 200u);
  EXPECT_EQ(reply.body, expected);
  reply = request(http::verb::get, "/audio?session=spoken", "", "Bearer key-a");
  EXPECT_EQ(reply.status, 200u);
  EXPECT_EQ(reply.body, expected);
}

TEST_F(ViewerTest, FollowerHearsAbortedWhenTheProducerGoesAway) {
  grpc::ClientContext context;
  auto producer = open_session(context, "waiting");
  WebSocketReply reply;
  std::promise<void> header_arrived;
  std::thread follower([&] { reply = follow("/ws?session=waiting", &header_arrived); });
  // The producer goes away once the follower has the header (the session's first message).
  const bool header_first = header_arrived.get_future().wait_for(std::chrono::seconds(10)) == std::future_status::ready;
  context.TryCancel();
  producer->Finish();
  follower.join();
  EXPECT_TRUE(header_first);
  EXPECT_EQ(reply.binary.size(), 1u);  // the header
  EXPECT_EQ(reply.close.code, 4000 + grpc::StatusCode::ABORTED);
  EXPECT_THAT(std::string(reply.close.reason.c_str()), ::testing::HasSubstr("producer"));
}

TEST_F(ViewerTest, ShutdownEndsAWaitingFollowerWithGoingAway) {
  grpc::ClientContext context;
  auto producer = open_session(context, "waiting");
  WebSocketReply reply;
  std::thread follower([&] { reply = follow("/ws?session=waiting"); });
  ASSERT_TRUE(eventually([&] { return server_->active_streams() == 2; }));
  server_->shutdown(std::chrono::milliseconds(0));
  follower.join();
  producer->Finish();
  EXPECT_EQ(reply.close.code, websocket::close_code::going_away);
  EXPECT_THAT(std::string(reply.close.reason.c_str()), ::testing::HasSubstr("shutting down"));
}

TEST(ViewerConfig, HttpListenIsOffByDefaultAndReadFromFlagAndEnvironment) {
  EXPECT_EQ(parse_command_line({}).config.http_listen, "");
  EXPECT_EQ(parse_command_line({"--http-listen", "127.0.0.1:8080"}).config.http_listen, "127.0.0.1:8080");
  const Environment environment = [](const std::string& name) -> std::optional<std::string> {
    if (name == "LIPSYNCD_HTTP_LISTEN") return "0.0.0.0:0";
    return std::nullopt;
  };
  EXPECT_EQ(parse_command_line({}, environment).config.http_listen, "0.0.0.0:0");
  EXPECT_THROW(parse_command_line({"--http-listen", "8080"}), ConfigError);
  EXPECT_THAT(help_text(), ::testing::HasSubstr("--http-listen"));
}

}  // namespace
}  // namespace lipsync::server
