// API keys, tenants and quotas (server/src/transport/tenants.hpp): the key file and the
// counting on their own, then every refusal and the session namespaces on a
// real lipsyncd (in-process on 127.0.0.1:0, the C++ client library sending the
// key), and the binary's start-up log, key-file errors and --hash-key.
#include "transport/tenants.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>

#include "../support/child_process.hpp"
#include "../support/json_log.hpp"
#include "../support/prometheus_text.hpp"
#include "../support/server_harness.hpp"
#include "lipsync/client/animation_client.hpp"

namespace lipsync::server {
namespace {

using namespace harness;
using ::testing::HasSubstr;
namespace fs = std::filesystem;

// --- the key file and the counting ----------------------------------------------

TEST(ApiKeys, KeysAreHashedWithSha256) {
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
}

TEST(ApiKeys, AKeyFileMapsHashedKeysToTenantsWithQuotas) {
  const KeyTable table = parse_key_file(R"({
    "tenants": {"studio": {"max_streams": 3, "max_phonemes_per_second": 40}, "lab": {}},
    "keys": [{"name": "tts", "tenant": "studio", "sha256": ")" +
                                            sha256_hex("k1") + R"(", "calls": ["Animate"]},
             {"tenant": "lab", "sha256": ")" +
                                            sha256_hex("k2") + R"("}]})",
                                        "keys.json");
  ASSERT_EQ(table.keys_by_hash.size(), 2u);
  const ApiKey& tts = table.keys_by_hash.at(sha256_hex("k1"));
  EXPECT_EQ(tts.tenant, "studio");
  EXPECT_EQ(tts.calls, std::set<std::string>{"Animate"});
  EXPECT_EQ(table.keys_by_hash.at(sha256_hex("k2")).name, sha256_hex("k2").substr(0, 8));
  EXPECT_EQ(table.tenants.at("studio")->max_streams, 3u);
  EXPECT_EQ(table.tenants.at("studio")->max_phonemes_per_second, 40u);
  EXPECT_EQ(table.tenants.at("studio")->max_sessions, kUnlimited);
  EXPECT_EQ(table.tenants.at("lab")->max_mesh_streams, kUnlimited);
}

TEST(ApiKeys, AKeyFileErrorNamesTheFileTheEntryAndTheProblem) {
  const std::string hash = sha256_hex("k");
  const std::pair<std::string, std::string> cases[] = {
      {"[1, 2]", "keys.json: expected a JSON object"},
      {"{\"tenants\": {}, \"keys\": [], \"extra\": 1}", "keys.json: extra: unknown field"},
      {"{\"tenants\": {\"a b\": {}}, \"keys\": []}", "keys.json: tenants.a b: a tenant name is"},
      {"{\"tenants\": {\"a\": {\"max_streams\": -1}}, \"keys\": []}", "tenants.a.max_streams: expected a whole number"},
      {"{\"tenants\": {\"a\": {\"max_streamz\": 1}}, \"keys\": []}", "tenants.a.max_streamz: unknown quota"},
      {"{\"tenants\": {\"a\": {}}, \"keys\": [{\"tenant\": \"a\", \"sha256\": \"abc\"}]}",
       "keys[0].sha256: expected 64 lowercase hexadecimal digits"},
      {"{\"tenants\": {\"a\": {}}, \"keys\": [{\"tenant\": \"b\", \"sha256\": \"" + hash + "\"}]}",
       "keys[0].tenant: no tenant 'b'"},
      {"{\"tenants\": {\"a\": {}}, \"keys\": [{\"tenant\": \"a\", \"key\": \"plain\", \"sha256\": \"" + hash + "\"}]}",
       "keys[0].key: unknown field"},
      {"{\"tenants\": {\"a\": {}}, \"keys\": [{\"tenant\": \"a\", \"sha256\": \"" + hash +
           "\"}, {\"tenant\": \"a\", \"sha256\": \"" + hash + "\"}]}",
       "keys[1]: the same sha256 as an earlier key"},
      {"{\"tenants\": {\"a\": {}}, \"keys\": [{\"tenant\": \"a\", \"calls\": [\"Delete\"], \"sha256\": \"" + hash +
           "\"}]}",
       "keys[0].calls: expected method names"},
  };
  for (const auto& [text, expected] : cases) {
    try {
      parse_key_file(text, "keys.json");
      ADD_FAILURE() << "accepted: " << text;
    } catch (const KeyFileError& error) {
      EXPECT_THAT(error.what(), HasSubstr(expected)) << text;
      EXPECT_THAT(error.what(), HasSubstr("--api-keys: keys.json")) << text;
    }
  }
}

TEST(TenantUsage, AQuotaRefusesTheOneTooManyNamingItsValueUntilOneIsReleased) {
  TenantUsage usage("studio");
  EXPECT_TRUE(usage.acquire(Quota::streams, 2).ok());
  EXPECT_TRUE(usage.acquire(Quota::streams, 2).ok());
  const grpc::Status refused = usage.acquire(Quota::streams, 2);
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("tenant 'studio' is at its quota max_streams=2"));
  EXPECT_TRUE(usage.acquire(Quota::sessions, 1).ok()) << "each quota counts on its own";
  usage.release(Quota::streams);
  EXPECT_TRUE(usage.acquire(Quota::streams, 2).ok());
  EXPECT_EQ(usage.in_use(Quota::streams), 2u);
}

TEST(TenantUsage, ThePhonemeBucketTakesABurstWholeThenRefusesUntilItHasRefilled) {
  TenantUsage usage("studio");
  const auto t0 = TenantUsage::Clock::now();
  EXPECT_TRUE(usage.take_phonemes(100, 50, t0).ok()) << "a full bucket takes more than it holds (debt)";
  const grpc::Status refused = usage.take_phonemes(1, 50, t0 + std::chrono::milliseconds(500));
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("max_phonemes_per_second=50"));
  EXPECT_TRUE(usage.take_phonemes(1, 50, t0 + std::chrono::milliseconds(1100)).ok());
  EXPECT_TRUE(usage.take_phonemes(1'000'000, kUnlimited, t0).ok());
}

// --- on a real server -----------------------------------------------------------

constexpr const char* kKeyA = "key-of-tenant-a-0001";
constexpr const char* kKeyQ = "key-of-tenant-q-0002";
constexpr const char* kKeyB = "key-of-tenant-b-0003";
constexpr const char* kKeyViewer = "viewer-key-of-a-0004";

std::string key_file_text(const std::string& extra_key = "") {
  std::string text = R"({"tenants": {
      "a": {"max_streams": 2},
      "q": {"max_sessions": 1, "max_subscribers": 1, "max_mesh_streams": 0, "max_phonemes_per_second": 50},
      "b": {}},
    "keys": [)";
  text += "{\"tenant\": \"a\", \"sha256\": \"" + sha256_hex(kKeyA) + "\"},";
  text += "{\"tenant\": \"q\", \"sha256\": \"" + sha256_hex(kKeyQ) + "\"},";
  text += "{\"tenant\": \"b\", \"sha256\": \"" + sha256_hex(kKeyB) + "\"},";
  if (!extra_key.empty()) text += "{\"tenant\": \"b\", \"sha256\": \"" + sha256_hex(extra_key) + "\"},";
  text += "{\"name\": \"viewer\", \"tenant\": \"a\", \"calls\": [\"Subscribe\"], \"sha256\": \"" +
          sha256_hex(kKeyViewer) + "\"}]}";
  return text;
}

class TenantServer : public LiveServerTest {
 protected:
  void SetUp() override {
    lipsync::testing::write_text(key_file_, key_file_text());
    ServerConfig config;
    config.api_keys = key_file_.string();
    config.metrics_listen = "127.0.0.1:0";
    start(config);
  }

  Exposition scrape() const {
    int status = 0;
    const std::string body = http_get(server_->metrics_address(), "/metrics", &status);
    EXPECT_EQ(status, 200);
    return parse_exposition(body);
  }

  client::AnimationClient client_with(const std::string& key) const {
    client::ClientOptions options;
    options.api_key = key;
    options.connect_timeout = std::chrono::milliseconds(5000);
    return client::AnimationClient(server_->address(), options);
  }

  /// A live producer of `session` ("" for none) that has received its header, or the refusal.
  struct Stream {
    std::unique_ptr<client::AnimateCall> call;
    std::shared_ptr<std::atomic<bool>> header = std::make_shared<std::atomic<bool>>(false);
    grpc::Status refusal;
  };
  Stream start_stream(const client::AnimationClient& client, const std::string& session, bool mesh = false,
                      std::uint32_t fps = 0) const {
    v1::AnimationSettings settings = session.empty() ? v1::AnimationSettings{} : session_settings(session);
    if (mesh) settings.mutable_outputs()->mutable_mesh()->set_enabled(true);
    if (fps != 0) settings.set_fps(fps);
    Stream stream;
    stream.call = client.start_animate(settings, [header = stream.header](const v1::TrackMessage& message) {
      if (message.has_header()) *header = true;
    });
    EXPECT_TRUE(eventually([&] { return *stream.header || stream.call->done(); }));
    if (stream.call->done()) stream.refusal = stream.call->wait();
    return stream;
  }

  static std::vector<v1::Phoneme> phonemes(std::size_t count) {
    std::vector<v1::Phoneme> result;
    for (const auto& interval : utterance(count)) result.push_back(to_proto(interval));
    return result;
  }

  static grpc::StatusCode code_of(const std::function<void()>& call, std::string* message = nullptr) {
    try {
      call();
    } catch (const client::CallError& error) {
      if (message) *message = error.server_message();
      return error.code();
    }
    return grpc::StatusCode::OK;
  }

  fs::path key_file_ = lipsync::testing::make_temp_dir("lipsync-keys-") / "keys.json";
};

TEST_F(TenantServer, ACallWithoutAKeyOrWithAnUnknownOrMalformedOneIsUnauthenticated) {
  std::string message;
  EXPECT_EQ(code_of([&] { client_with("").list_models(); }, &message), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_THAT(message, HasSubstr("authorization: Bearer"));
  EXPECT_EQ(code_of([&] { client_with("not-a-key").render({}, phonemes(5)); }, &message),
            grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(
      message,
      "unknown API key: it is not in this server's key file (check the key sent as `authorization: Bearer <key>`)");
  Stream refused = start_stream(client_with(""), "s");
  EXPECT_EQ(refused.refusal.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(code_of([&] { client_with("").subscribe("s", v1::SubscribeRequest::START_FROM_BEGINNING); }),
            grpc::StatusCode::UNAUTHENTICATED);

  auto stub = v1::LipSync::NewStub(connect(server_->address()));
  grpc::ClientContext context;
  context.AddMetadata("authorization", std::string("Basic ") + kKeyA);
  v1::ListModelsResponse response;
  const grpc::Status malformed = stub->ListModels(&context, {}, &response);
  EXPECT_EQ(malformed.error_code(), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_THAT(malformed.error_message(), HasSubstr("Bearer <key>"));

  EXPECT_EQ(code_of([&] { client_with(kKeyA).list_models(); }), grpc::StatusCode::OK);
}

TEST_F(TenantServer, SpeakNeedsAKeyAllowedToSpeakAndPublishesInTheTenantsNamespace) {
  v1::SpeakRequest request;
  request.set_text("Papa parked.");
  std::string message;
  EXPECT_EQ(code_of([&] { client_with("").speak(request); }, &message), grpc::StatusCode::UNAUTHENTICATED);
  EXPECT_EQ(code_of([&] { client_with(kKeyViewer).speak(request); }, &message), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_THAT(message, HasSubstr("may not call Speak"));
  request.mutable_settings()->set_session("spoken");
  EXPECT_EQ(code_of([&] { client_with(kKeyA).speak(request); }), grpc::StatusCode::OK);
  // Tenant b does not see tenant a's session; tenant a's own viewer key does.
  EXPECT_EQ(code_of([&] { client_with(kKeyB).subscribe("spoken", v1::SubscribeRequest::START_FROM_BEGINNING); }),
            grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(code_of([&] { client_with(kKeyViewer).subscribe("spoken", v1::SubscribeRequest::START_FROM_BEGINNING); }),
            grpc::StatusCode::OK);
}

TEST_F(TenantServer, AKeyLimitedToSomeCallsIsDeniedTheOthers) {
  std::string message;
  EXPECT_EQ(code_of([&] { client_with(kKeyViewer).render({}, phonemes(5)); }, &message),
            grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_THAT(message, HasSubstr("API key 'viewer' of tenant 'a' may not call Render (it may call Subscribe)"));
  EXPECT_EQ(start_stream(client_with(kKeyViewer), "").refusal.error_code(), grpc::StatusCode::PERMISSION_DENIED);
  // Subscribe is let through to the session lookup.
  EXPECT_EQ(code_of([&] { client_with(kKeyViewer).subscribe("none", v1::SubscribeRequest::START_FROM_BEGINNING); }),
            grpc::StatusCode::NOT_FOUND);
}

TEST_F(TenantServer, TheStreamQuotaRefusesTheTenantsNextStreamAndNoOtherTenants) {
  const auto a = client_with(kKeyA);
  Stream first = start_stream(a, "");
  Stream second = start_stream(a, "");
  ASSERT_TRUE(*first.header && *second.header);
  Stream third = start_stream(a, "");
  EXPECT_EQ(third.refusal.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(third.refusal.error_message(), HasSubstr("tenant 'a' is at its quota max_streams=2"));
  Stream other_tenant = start_stream(client_with(kKeyB), "");
  EXPECT_TRUE(*other_tenant.header) << other_tenant.refusal.error_message();
  first.call->end();
  EXPECT_TRUE(first.call->wait().ok());
  // The quota is released when the server has ended the call, a moment after the client saw it end.
  Stream after_release;
  EXPECT_TRUE(eventually([&] {
    after_release = start_stream(a, "");
    return bool(*after_release.header);
  })) << after_release.refusal.error_message();
}

TEST_F(TenantServer, TheStreamAndSessionGaugesCountEachTenantApart) {
  const auto a = client_with(kKeyA);
  const auto b = client_with(kKeyB);
  Stream a_session = start_stream(a, "a-live");
  Stream a_private = start_stream(a, "");
  Stream b_session = start_stream(b, "b-live");
  ASSERT_TRUE(*a_session.header && *a_private.header && *b_session.header);
  std::atomic<bool> followed = false;
  const auto b_follower =
      b.start_subscribe("b-live", v1::SubscribeRequest::START_FROM_BEGINNING, [&](const v1::TrackMessage& message) {
        if (message.has_header()) followed = true;
      });
  ASSERT_TRUE(eventually([&] { return followed.load(); }));

  const Exposition live = scrape();
  EXPECT_EQ(live.at(R"(lipsyncd_streams{method="Animate",state="open",tenant="a"})"), 2);
  EXPECT_EQ(live.at(R"(lipsyncd_streams{method="Animate",state="open",tenant="b"})"), 1);
  EXPECT_EQ(live.value_or_zero(R"(lipsyncd_streams{method="Subscribe",state="open",tenant="a"})"), 0);
  EXPECT_EQ(live.at(R"(lipsyncd_streams{method="Subscribe",state="open",tenant="b"})"), 1);
  EXPECT_EQ(live.at(R"(lipsyncd_sessions{state="live",tenant="a"})"), 1);
  EXPECT_EQ(live.at(R"(lipsyncd_sessions{state="live",tenant="b"})"), 1);
  EXPECT_EQ(live.samples.count(R"(lipsyncd_streams{method="Animate",state="open",tenant=""})"), 0u)
      << "a server with keys has no anonymous tenant";

  a_session.call->end();
  EXPECT_TRUE(a_session.call->wait().ok());
  // Counted down when gRPC is done with the call, a moment after the client has its status.
  ASSERT_TRUE(eventually([&] {
    const Exposition now = scrape();
    return now.at(R"(lipsyncd_streams{method="Animate",state="open",tenant="a"})") == 1 &&
           now.at(R"(lipsyncd_sessions{state="ended",tenant="a"})") == 1;
  }));
  const Exposition one_ended = scrape();
  EXPECT_EQ(one_ended.at(R"(lipsyncd_sessions{state="live",tenant="a"})"), 0);
  EXPECT_EQ(one_ended.at(R"(lipsyncd_sessions{state="live",tenant="b"})"), 1);
  EXPECT_EQ(one_ended.at(R"(lipsyncd_streams{method="Animate",state="open",tenant="b"})"), 1);
  a_private.call->end();
  b_session.call->end();
  EXPECT_TRUE(a_private.call->wait().ok());
  EXPECT_TRUE(b_session.call->wait().ok());
  EXPECT_TRUE(b_follower->wait().ok());
}

TEST_F(TenantServer, TheSessionAndSubscriberQuotasRefuseNamingTheQuota) {
  const auto q = client_with(kKeyQ);
  Stream producer = start_stream(q, "q-one");
  ASSERT_TRUE(*producer.header) << producer.refusal.error_message();
  Stream second_session = start_stream(q, "q-two");
  EXPECT_EQ(second_session.refusal.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(second_session.refusal.error_message(), HasSubstr("max_sessions=1"));

  // Attached (its header replayed), so it holds the subscriber quota: counted as an open stream
  // it is from a moment before, and a second subscriber in that moment was let in, then waited forever.
  std::atomic<bool> first_attached = false;
  auto first =
      q.start_subscribe("q-one", v1::SubscribeRequest::START_FROM_BEGINNING, [&](const v1::TrackMessage& message) {
        if (message.has_header()) first_attached = true;
      });
  ASSERT_TRUE(eventually([&] { return first_attached.load(); }));
  auto second = q.start_subscribe("q-one", v1::SubscribeRequest::START_FROM_BEGINNING, {});
  const grpc::Status refused = second->wait();
  EXPECT_EQ(refused.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(refused.error_message(), HasSubstr("max_subscribers=1"));
  producer.call->end();
  EXPECT_TRUE(producer.call->wait().ok());
  EXPECT_TRUE(first->wait().ok());
}

TEST_F(TenantServer, TheMeshQuotaAndThePhonemeRateRefuseNamingTheQuota) {
  const auto q = client_with(kKeyQ);
  v1::AnimationSettings mesh;
  mesh.mutable_outputs()->mutable_mesh()->set_enabled(true);
  std::string message;
  EXPECT_EQ(code_of([&] { q.render(mesh, phonemes(5)); }, &message), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(message, HasSubstr("max_mesh_streams=0"));
  Stream mesh_stream = start_stream(q, "", true);
  EXPECT_EQ(mesh_stream.refusal.error_code(), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(mesh_stream.refusal.error_message(), HasSubstr("max_mesh_streams=0"));

  // 50 phonemes a second: a Render of 60 is taken whole, the next one at once is refused.
  EXPECT_EQ(code_of([&] { q.render({}, phonemes(60)); }), grpc::StatusCode::OK);
  EXPECT_EQ(code_of([&] { q.render({}, phonemes(60)); }, &message), grpc::StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_THAT(message, HasSubstr("tenant 'q' is over its quota max_phonemes_per_second=50"));
  EXPECT_EQ(code_of([&] { client_with(kKeyB).render({}, phonemes(60)); }), grpc::StatusCode::OK);
}

TEST_F(TenantServer, ATenantCannotSeeSubscribeToOrCollideWithAnotherTenantsSession) {
  const auto a = client_with(kKeyA);
  const auto b = client_with(kKeyB);
  std::string never_opened;
  EXPECT_EQ(code_of([&] { b.subscribe("shared", v1::SubscribeRequest::START_FROM_BEGINNING); }, &never_opened),
            grpc::StatusCode::NOT_FOUND);

  Stream a_producer = start_stream(a, "shared", false, 30);
  ASSERT_TRUE(*a_producer.header) << a_producer.refusal.error_message();
  std::string someone_elses;
  EXPECT_EQ(code_of([&] { b.subscribe("shared", v1::SubscribeRequest::START_FROM_BEGINNING); }, &someone_elses),
            grpc::StatusCode::NOT_FOUND);
  EXPECT_EQ(someone_elses, never_opened) << "another tenant's session must read as one that does not exist";

  // The same name in b's namespace is b's own session, beside a's.
  Stream b_producer = start_stream(b, "shared", false, 50);
  ASSERT_TRUE(*b_producer.header) << b_producer.refusal.error_message();
  std::atomic<std::uint32_t> a_fps = 0, b_fps = 0;
  auto a_subscriber =
      a.start_subscribe("shared", v1::SubscribeRequest::START_FROM_BEGINNING, [&](const v1::TrackMessage& m) {
        if (m.has_header()) a_fps = m.header().fps();
      });
  auto b_subscriber =
      b.start_subscribe("shared", v1::SubscribeRequest::START_FROM_BEGINNING, [&](const v1::TrackMessage& m) {
        if (m.has_header()) b_fps = m.header().fps();
      });
  ASSERT_TRUE(eventually([&] { return a_fps != 0 && b_fps != 0; }));
  EXPECT_EQ(a_fps, 30u);
  EXPECT_EQ(b_fps, 50u);
  // Within a tenant the name still collides.
  Stream b_again = start_stream(b, "shared");
  EXPECT_EQ(b_again.refusal.error_code(), grpc::StatusCode::ALREADY_EXISTS);
  EXPECT_THAT(b_again.refusal.error_message(), HasSubstr("session 'shared'"));
  EXPECT_THAT(b_again.refusal.error_message(), ::testing::Not(HasSubstr("b/")));
  a_producer.call->end();
  b_producer.call->end();
  EXPECT_TRUE(a_subscriber->wait().ok());
  EXPECT_TRUE(b_subscriber->wait().ok());
}

TEST_F(TenantServer, AReloadedKeyFileAppliesToNewCallsAndABadOneKeepsTheOld) {
  const std::string added = "key-added-by-reload-0005";
  EXPECT_EQ(code_of([&] { client_with(added).list_models(); }), grpc::StatusCode::UNAUTHENTICATED);
  lipsync::testing::write_text(key_file_, key_file_text(added));
  server_->reload_credentials();
  EXPECT_EQ(code_of([&] { client_with(added).list_models(); }), grpc::StatusCode::OK);
  lipsync::testing::write_text(key_file_, "{\"tenants\": ");
  server_->reload_credentials();
  EXPECT_EQ(code_of([&] { client_with(added).list_models(); }), grpc::StatusCode::OK);
}

// --- the binary ------------------------------------------------------------------

TEST(LipsyncdKeys, TheStartUpLogSaysWhetherTheServerIsOpenOrHowManyKeysItHas) {
  const fs::path work = lipsync::testing::make_temp_dir("lipsyncd-keys-");
  lipsync::testing::write_text(work / "keys.json", key_file_text());
  for (const bool with_keys : {false, true}) {
    std::vector<std::string> argv = {LIPSYNCD_PATH, "--listen", "127.0.0.1:0"};
    if (with_keys) argv.insert(argv.end(), {"--api-keys", (work / "keys.json").string()});
    const fs::path run = work / (with_keys ? "with-keys" : "open");
    fs::create_directory(run);
    lipsync::testing::ChildProcess server(argv, work, run / "out", run / "err");
    ASSERT_FALSE(lipsync::testing::wait_for_listening_address(run / "out").empty());
    server.terminate();
    EXPECT_EQ(server.wait(), 0);
    const std::string log = lipsync::testing::read_text(run / "err");
    EXPECT_THAT(log, HasSubstr(with_keys ? "callers: 4 API keys of 3 tenants from " : "callers: open to every caller"));
  }
}

// Both access lines of a keyed call name its tenant (the start line used to be written before
// the key was checked, with tenant "").
TEST(LipsyncdKeys, JsonAccessLinesOfASubscribeNameTheTenantOfItsKey) {
  const fs::path work = lipsync::testing::make_temp_dir("lipsyncd-keys-");
  lipsync::testing::write_text(work / "keys.json", R"({"tenants": {"studio": {}}, "keys": [{"tenant": "studio", )"
                                                   R"("sha256": ")" +
                                                       sha256_hex("studio-key") + R"("}]})");
  lipsync::testing::ChildProcess server(
      {LIPSYNCD_PATH, "--listen", "127.0.0.1:0", "--api-keys", (work / "keys.json").string(), "--log-format", "json"},
      work, work / "out", work / "err");
  const std::string address = lipsync::testing::wait_for_listening_address(work / "out");
  ASSERT_FALSE(address.empty()) << lipsync::testing::read_text(work / "err");
  client::ClientOptions options;
  options.api_key = "studio-key";
  try {
    client::AnimationClient(address, options).subscribe("nothing-here", v1::SubscribeRequest::START_FROM_BEGINNING);
    ADD_FAILURE() << "a subscription to a session that does not exist succeeded";
  } catch (const client::CallError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::NOT_FOUND) << error.what();
  }
  server.terminate();
  EXPECT_EQ(server.wait(), 0);
  const auto lines = lipsync::testing::json_lines(lipsync::testing::read_text(work / "err"));
  const auto* start = lipsync::testing::find_event(lines, "Subscribe.start");
  const auto* end = lipsync::testing::find_event(lines, "Subscribe.end");
  ASSERT_TRUE(start && end) << lipsync::testing::read_text(work / "err");
  EXPECT_EQ((*start)["tenant"], "studio");
  EXPECT_EQ((*end)["tenant"], "studio");
  EXPECT_EQ((*end)["status"], "NOT_FOUND");
}

TEST(LipsyncdKeys, ABadKeyFileExits1NamingTheFileAndTheEntry) {
  const fs::path work = lipsync::testing::make_temp_dir("lipsyncd-keys-");
  lipsync::testing::write_text(work / "keys.json",
                               R"({"tenants": {"a": {}}, "keys": [{"tenant": "a", "sha256": "x"}]})");
  const auto run = lipsync::testing::run_program(
      {LIPSYNCD_PATH, "--listen", "127.0.0.1:0", "--api-keys", (work / "keys.json").string()}, work, work);
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr((work / "keys.json").string() + ": keys[0].sha256: expected 64"));
}

TEST(LipsyncdKeys, HashKeyPrintsTheSha256OfTheKeyOnStandardInput) {
  const fs::path work = lipsync::testing::make_temp_dir("lipsyncd-keys-");
  lipsync::testing::write_text(work / "key", "my-secret-key\n");
  const auto run = lipsync::testing::run_program({LIPSYNCD_PATH, "--hash-key"}, work, work,
                                                 {.stdin_file = work / "key", .path_env = std::nullopt});
  EXPECT_EQ(run.status, 0) << run.err;
  EXPECT_EQ(run.out, sha256_hex("my-secret-key") + "\n");
}

}  // namespace
}  // namespace lipsync::server
