// TLS and mutual TLS on a real lipsyncd, with certificates made by openssl at
// test time (tests/support/make_test_certs.sh): a CA, server certificates for
// localhost and 127.0.0.1, a client certificate, and an unrelated CA with its
// own client and server. In-process servers on 127.0.0.1:0 for who is let in;
// the lipsyncd binary for start-up errors, SIGHUP reloads and the CLI.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <future>
#include <vector>

#include "../support/child_process.hpp"
#include "../support/json_log.hpp"
#include "../support/server_harness.hpp"
#include "lipsync/client/animation_client.hpp"

namespace lipsync::server {
namespace {

using namespace harness;
using ::testing::HasSubstr;
namespace fs = std::filesystem;

/// The certificates: made by the ctest fixture tls_test_certificates (LIPSYNC_TEST_CERTIFICATES),
/// else once for this process.
const fs::path& certificates() {
  static const fs::path directory = [] {
    if (const char* made = std::getenv("LIPSYNC_TEST_CERTIFICATES")) return fs::path(made);
    const fs::path made = lipsync::testing::make_temp_dir("lipsync-tls-test-");
    const std::string command =
        std::string("bash ") + LIPSYNC_SOURCE_DIR + "/tests/support/make_test_certs.sh " + made.string();
    if (std::system(command.c_str()) != 0) throw std::runtime_error("make_test_certs.sh failed: " + command);
    return made;
  }();
  return directory;
}

std::string pem(const std::string& name) { return lipsync::testing::read_text(certificates() / name); }
std::string cert_path(const std::string& name) { return (certificates() / name).string(); }

/// A new connection (its own subchannel) to `address`: TLS trusting `ca` (with a client
/// certificate `client` if given), or plaintext when `ca` is empty.
std::shared_ptr<grpc::Channel> connect_new(const std::string& address, const std::string& ca,
                                           const std::string& client = "") {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  if (ca.empty()) return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
  grpc::SslCredentialsOptions options;
  options.pem_root_certs = pem(ca + ".pem");
  if (!client.empty()) {
    options.pem_cert_chain = pem(client + ".pem");
    options.pem_private_key = pem(client + ".key");
  }
  return grpc::CreateCustomChannel(address, grpc::SslCredentials(options), args);
}

struct Answer {
  grpc::Status status;
  std::string server_name;  ///< the common name of the certificate the server presented
};

Answer list_models(const std::shared_ptr<grpc::Channel>& channel) {
  auto stub = v1::LipSync::NewStub(channel);
  grpc::ClientContext context;
  context.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(5));
  v1::ListModelsResponse response;
  Answer answer{stub->ListModels(&context, {}, &response), ""};
  if (answer.status.ok()) {
    const auto names = context.auth_context()->FindPropertyValues("x509_common_name");
    if (!names.empty()) answer.server_name = std::string(names.front().data(), names.front().size());
  }
  return answer;
}

ServerConfig tls_config(bool mutual) {
  ServerConfig config;
  config.tls_cert = cert_path("server.pem");
  config.tls_key = cert_path("server.key");
  if (mutual) config.tls_client_ca = cert_path("ca.pem");
  return config;
}

class TlsServer : public LiveServerTest {
 protected:
  void SetUp() override { start(tls_config(false)); }
};

class MutualTlsServer : public LiveServerTest {
 protected:
  void SetUp() override { start(tls_config(true)); }
};

TEST_F(TlsServer, APlaintextClientIsRefusedAndATlsClientIsServed) {
  EXPECT_EQ(list_models(connect_new(server_->address(), "")).status.error_code(), grpc::StatusCode::UNAVAILABLE);
  const Answer served = list_models(connect_new(server_->address(), "ca"));
  EXPECT_TRUE(served.status.ok()) << served.status.error_message();
  EXPECT_EQ(served.server_name, "lipsyncd");
}

TEST_F(TlsServer, AClientThatTrustsAnotherCaIsRefused) {
  const Answer refused = list_models(connect_new(server_->address(), "other-ca"));
  EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::UNAVAILABLE) << refused.status.error_message();
}

TEST_F(TlsServer, TheClientLibraryAnimatesOverTlsAsOverPlaintext) {
  client::ClientOptions options;
  options.tls.ca_file = cert_path("ca.pem");
  const client::AnimationClient secure(server_->address(), options);
  secure.wait_connected();
  std::vector<v1::Phoneme> phonemes;
  for (const auto& interval : utterance(12)) phonemes.push_back(to_proto(interval));
  const client::ReceivedTrack track = secure.render({}, phonemes);
  ASSERT_TRUE(track.summary.has_value());
  EXPECT_GT(track.track.frame_count(), 0u);
  EXPECT_EQ(track.summary->frames(), track.track.frame_count());

  client::ClientOptions wrong_ca;
  wrong_ca.tls.ca_file = cert_path("other-ca.pem");
  wrong_ca.connect_timeout = std::chrono::milliseconds(1500);
  try {
    client::AnimationClient(server_->address(), wrong_ca).render({}, phonemes);
    ADD_FAILURE() << "a client that trusts another CA rendered";
  } catch (const client::CallError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::UNAVAILABLE) << error.what();
  }
}

TEST(TlsClientOptions, AnUnreadableCaFileIsNamed) {
  client::ClientOptions options;
  options.tls.ca_file = "/nonexistent/ca.pem";
  try {
    client::AnimationClient("127.0.0.1:1", options);
    ADD_FAILURE() << "no error for a missing CA file";
  } catch (const client::CallError& error) {
    EXPECT_EQ(error.code(), grpc::StatusCode::INVALID_ARGUMENT);
    EXPECT_THAT(error.what(), HasSubstr("/nonexistent/ca.pem"));
  }
}

TEST_F(MutualTlsServer, AClientWithoutACertificateIsRefused) {
  const Answer refused = list_models(connect_new(server_->address(), "ca"));
  EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::UNAVAILABLE) << refused.status.error_message();
}

TEST_F(MutualTlsServer, AClientCertificateFromAnotherCaIsRefused) {
  const Answer refused = list_models(connect_new(server_->address(), "ca", "other-client"));
  EXPECT_EQ(refused.status.error_code(), grpc::StatusCode::UNAVAILABLE) << refused.status.error_message();
}

TEST_F(MutualTlsServer, TheCaSignedClientIsServedThroughTheClientLibrary) {
  client::ClientOptions options;
  options.tls = {.enabled = true,
                 .ca_file = cert_path("ca.pem"),
                 .cert_file = cert_path("client.pem"),
                 .key_file = cert_path("client.key")};
  const client::AnimationClient secure(server_->address(), options);
  const auto models = secure.list_models();
  ASSERT_GE(models.models_size(), 1);
  EXPECT_TRUE(list_models(connect_new(server_->address(), "ca", "client")).status.ok());
}

// --- the binary ------------------------------------------------------------------

struct RunningServer {
  fs::path directory = lipsync::testing::make_temp_dir("lipsyncd-tls-run-");
  std::unique_ptr<lipsync::testing::ChildProcess> process;
  std::string address;

  explicit RunningServer(std::vector<std::string> flags) {
    flags.insert(flags.begin(), {LIPSYNCD_PATH, "--listen", "127.0.0.1:0"});
    process = std::make_unique<lipsync::testing::ChildProcess>(flags, directory, directory / "out", directory / "err");
    address = lipsync::testing::wait_for_listening_address(directory / "out");
  }
  std::string log() const { return lipsync::testing::read_text(directory / "err"); }
};

TEST(LipsyncdTls, StartUpWithAnUnreadableCertificateExits1NamingTheFile) {
  const fs::path work = lipsync::testing::make_temp_dir("lipsyncd-tls-bad-");
  const auto run = lipsync::testing::run_program({LIPSYNCD_PATH, "--listen", "127.0.0.1:0", "--tls-cert",
                                                  "/nonexistent/cert.pem", "--tls-key", cert_path("server.key")},
                                                 work, work);
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("--tls-cert: cannot read '/nonexistent/cert.pem'"));
}

TEST(LipsyncdTls, StartUpWithAKeyThatIsNotTheCertificatesExits1NamingBoth) {
  const fs::path work = lipsync::testing::make_temp_dir("lipsyncd-tls-bad-");
  const auto run = lipsync::testing::run_program({LIPSYNCD_PATH, "--listen", "127.0.0.1:0", "--tls-cert",
                                                  cert_path("server.pem"), "--tls-key", cert_path("server2.key")},
                                                 work, work);
  EXPECT_EQ(run.status, 1);
  EXPECT_THAT(run.err, HasSubstr("does not belong to the certificate"));
  EXPECT_THAT(run.err, HasSubstr(cert_path("server2.key")));
}

TEST(LipsyncdTls, SighupServesAReplacedCertificateToNewConnectionsWhileAnOpenStreamGoesOn) {
  const fs::path work = lipsync::testing::make_temp_dir("lipsyncd-tls-reload-");
  const auto install = [&](const std::string& cert, const std::string& key) {
    fs::copy_file(certificates() / cert, work / "cert.pem", fs::copy_options::overwrite_existing);
    fs::copy_file(certificates() / key, work / "key.pem", fs::copy_options::overwrite_existing);
  };
  install("server.pem", "server.key");
  RunningServer server({"--tls-cert", (work / "cert.pem").string(), "--tls-key", (work / "key.pem").string()});
  ASSERT_FALSE(server.address.empty()) << server.log();
  EXPECT_THAT(server.log(), HasSubstr("transport: TLS"));
  EXPECT_EQ(list_models(connect_new(server.address, "ca")).server_name, "lipsyncd");

  auto stream_channel = connect_new(server.address, "ca");
  auto stub = v1::LipSync::NewStub(stream_channel);
  const auto intervals = utterance(40);
  Producer producer(*stub, session_settings("through-reload"));
  auto chunks = chunked(intervals, 10);
  producer.write(chunks[0]);
  producer.read_frames(1);

  // A mismatched pair is refused: logged, and the old certificate stays.
  install("server2.pem", "server.key");
  server.process->signal(SIGHUP);
  ASSERT_TRUE(eventually([&] { return server.log().find("TLS files not reloaded") != std::string::npos; }));
  EXPECT_THAT(server.log(), HasSubstr("does not belong to the certificate"));
  EXPECT_EQ(list_models(connect_new(server.address, "ca")).server_name, "lipsyncd");

  // The good new pair reaches new connections.
  install("server2.pem", "server2.key");
  server.process->signal(SIGHUP);
  EXPECT_TRUE(eventually([&] {
    return list_models(connect_new(server.address, "ca")).server_name == "lipsyncd-reloaded";
  })) << server.log();

  for (std::size_t i = 1; i < chunks.size(); ++i) producer.write(chunks[i]);
  producer.write(end_request());
  const Received received = producer.finish();
  EXPECT_TRUE(received.status.ok()) << received.status.error_message();
  ASSERT_TRUE(received.summary.has_value());
  EXPECT_EQ(received.summary->phonemes(), intervals.size());
  server.process->terminate();
  EXPECT_EQ(server.process->wait(), 0);
}

// gRPC core logs a failed handshake itself; in --log-format json that line must be a JSON
// object like every other (it was gRPC's own "E1127 ..." text).
TEST(LipsyncdTls, InJsonLogFormatGrpcsOwnHandshakeErrorIsAJsonLineToo) {
  RunningServer server(
      {"--tls-cert", cert_path("server.pem"), "--tls-key", cert_path("server.key"), "--log-format", "json"});
  ASSERT_FALSE(server.address.empty()) << server.log();
  EXPECT_EQ(list_models(connect_new(server.address, "")).status.error_code(), grpc::StatusCode::UNAVAILABLE);
  ASSERT_TRUE(eventually([&] { return server.log().find("Handshake failed") != std::string::npos; })) << server.log();
  server.process->terminate();
  EXPECT_EQ(server.process->wait(), 0);
  std::size_t handshake_errors = 0;
  for (const auto& object : lipsync::testing::json_lines(server.log())) {  // each line must be an object
    if (object.value("message", "").find("Handshake failed") != std::string::npos) {
      ++handshake_errors;
      EXPECT_EQ(object["level"], "error") << object.dump();
      EXPECT_EQ(object["message"].get<std::string>().rfind("grpc: ", 0), 0u) << object.dump();
    }
  }
  EXPECT_GT(handshake_errors, 0u);
}

TEST(LipsyncdTls, TheCliConnectsWithItsCaCertAndKeyOptions) {
  RunningServer server({"--tls-cert", cert_path("server.pem"), "--tls-key", cert_path("server.key"), "--tls-client-ca",
                        cert_path("ca.pem")});
  ASSERT_FALSE(server.address.empty()) << server.log();
  const fs::path work = lipsync::testing::make_temp_dir("lipsync-cli-tls-");
  const auto served = lipsync::testing::run_program(
      {LIPSYNC_CLI_BINARY, "server-models", "--server", server.address, "--ca", cert_path("ca.pem"), "--cert",
       cert_path("client.pem"), "--key", cert_path("client.key")},
      work, work);
  EXPECT_EQ(served.status, 0) << served.err;
  EXPECT_THAT(served.out, HasSubstr("model default"));
  const auto health = lipsync::testing::run_program(
      {LIPSYNC_CLI_BINARY, "health", "--server", server.address, "--ca", cert_path("ca.pem"), "--cert",
       cert_path("client.pem"), "--key", cert_path("client.key")},
      work, work);
  EXPECT_EQ(health.status, 0) << health.err;
  const auto without_certificate = lipsync::testing::run_program(
      {LIPSYNC_CLI_BINARY, "server-models", "--server", server.address, "--ca", cert_path("ca.pem"), "--timeout", "1"},
      work, work);
  EXPECT_EQ(without_certificate.status, 1);
  server.process->terminate();
  EXPECT_EQ(server.process->wait(), 0);
}

// A CLI command that gives up on a server (here: a handshake refused for want of a client
// certificate, retried by gRPC's own threads) must end with its status, never a signal. It used
// to die with SIGSEGV in about 3 % of runs: OpenSSL's exit handler freed what a gRPC thread was
// still using (clients/cli/main.cpp, end_process). 24 runs, four at a time, since the race is
// likelier on a busy machine.
TEST(LipsyncdTls, ACliCommandThatGivesUpOnAHandshakeEndsWithItsStatusNotASignal) {
  RunningServer server({"--tls-cert", cert_path("server.pem"), "--tls-key", cert_path("server.key"), "--tls-client-ca",
                        cert_path("ca.pem")});
  ASSERT_FALSE(server.address.empty()) << server.log();
  // One working folder per concurrent run (each captures its stdout and stderr there), reused by every round.
  std::vector<fs::path> works;
  for (int i = 0; i < 4; ++i) works.push_back(lipsync::testing::make_temp_dir("lipsync-cli-tls-"));
  for (int round = 0; round < 6; ++round) {
    std::vector<std::future<lipsync::testing::RunResult>> runs;
    for (const fs::path& work : works) {
      runs.push_back(std::async(std::launch::async, [&server, work] {
        return lipsync::testing::run_program({LIPSYNC_CLI_BINARY, "server-models", "--server", server.address, "--ca",
                                              cert_path("ca.pem"), "--timeout", "1"},
                                             work, work);
      }));
    }
    for (auto& run : runs) {
      const auto result = run.get();
      EXPECT_EQ(result.status, 1) << result.err;
      EXPECT_THAT(result.err, HasSubstr("do --ca, --cert and --key match"));
    }
  }
  for (const fs::path& work : works) fs::remove_all(work);
  server.process->terminate();
  EXPECT_EQ(server.process->wait(), 0);
}

// A plaintext client of a TLS server cannot tell a TLS server from a silent one, so its hint names
// both: the client library's (stream, server-models, ...), health's and loadtest's own HTTP/2 client's.
TEST(LipsyncdTls, PlaintextCliCommandsAgainstATlsServerSuggestTheTlsOptions) {
  RunningServer server({"--tls-cert", cert_path("server.pem"), "--tls-key", cert_path("server.key")});
  ASSERT_FALSE(server.address.empty()) << server.log();
  const fs::path work = lipsync::testing::make_temp_dir("lipsync-cli-tls-");
  const auto models = lipsync::testing::run_program(
      {LIPSYNC_CLI_BINARY, "server-models", "--server", server.address, "--timeout", "1"}, work, work);
  EXPECT_EQ(models.status, 1);
  EXPECT_THAT(models.err, HasSubstr("if it uses TLS, add --ca FILE or --tls"));
  const auto health = lipsync::testing::run_program(
      {LIPSYNC_CLI_BINARY, "health", "--server", server.address, "--timeout", "1"}, work, work);
  EXPECT_EQ(health.status, 1);
  EXPECT_THAT(health.err, HasSubstr("did not answer: DEADLINE_EXCEEDED"));
  EXPECT_THAT(health.err, HasSubstr("if it uses TLS, add --ca FILE or --tls"));
  const auto load = lipsync::testing::run_program(
      {LIPSYNC_CLI_BINARY, "loadtest", "--server", server.address, "--producers", "1", "--duration", "1"}, work, work);
  EXPECT_EQ(load.status, 1);
  EXPECT_THAT(load.err, HasSubstr("did not answer as a plaintext HTTP/2 (gRPC) server; if it uses TLS, run loadtest "
                                  "with --client grpc and --tls/--ca"));
  server.process->terminate();
  EXPECT_EQ(server.process->wait(), 0);
}

}  // namespace
}  // namespace lipsync::server
