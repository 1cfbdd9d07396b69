// The Prometheus endpoint (--metrics-listen) scraped during real calls on a real
// server: the text parses as the exposition format, and the counters, gauges and
// histograms move exactly as the calls made them; the Grafana dashboard in
// deploy/grafana only queries metrics the server exports.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>

#include "../support/child_process.hpp"
#include "../support/prometheus_text.hpp"
#include "../support/server_harness.hpp"
#include "transport/tenants.hpp"

namespace lipsync::server {
namespace {

using namespace harness;

class MetricsTest : public LiveServerTest {
 protected:
  void SetUp() override {
    ServerConfig config;
    config.metrics_listen = "127.0.0.1:0";
    start(config);
  }
  Exposition scrape() {
    int status = 0;
    const std::string body = http_get(server_->metrics_address(), "/metrics", &status);
    EXPECT_EQ(status, 200);
    return parse_exposition(body);
  }
};

TEST_F(MetricsTest, CountersAndGaugesMoveWithTheCalls) {
  const Exposition before = scrape();
  EXPECT_EQ(before.at(R"(lipsyncd_streams{method="Animate",state="open",tenant=""})"), 0);
  EXPECT_GT(before.samples.count("lipsyncd_build_info{version=\"" LIPSYNCD_VERSION "\",grpc_version=\"" +
                                 grpc::Version() + "\"}"),
            0u);

  const auto intervals = utterance(20, 5);
  Producer producer(*stub_, session_settings("measured"));
  const Exposition live = scrape();
  EXPECT_EQ(live.at(R"(lipsyncd_streams{method="Animate",state="open",tenant=""})"), 1);
  EXPECT_EQ(live.at(R"(lipsyncd_sessions{state="live",tenant=""})"), 1);
  for (const auto& request : chunked(intervals, 7)) producer.write(request);
  producer.write(end_request());
  const Received produced = producer.finish();
  ASSERT_TRUE(produced.status.ok()) << produced.status.error_message();
  const Received followed = subscribe_all(*stub_, "measured");
  ASSERT_TRUE(followed.status.ok()) << followed.status.error_message();
  grpc::ClientContext context;
  v1::GetModelRequest unknown;
  unknown.set_name("no-such-model");
  v1::ModelInfo info;
  EXPECT_EQ(stub_->GetModel(&context, unknown, &info).error_code(), grpc::StatusCode::NOT_FOUND);

  // Each call is counted when gRPC is done with it, a moment after the client has its status.
  ASSERT_TRUE(eventually([&] {
    const Exposition now = scrape();
    return now.value_or_zero(R"(lipsyncd_calls_total{method="Subscribe",code="OK",tenant=""})") == 1 &&
           now.value_or_zero(R"(lipsyncd_calls_total{method="Animate",code="OK",tenant=""})") == 1 &&
           now.value_or_zero(R"(lipsyncd_calls_total{method="GetModel",code="NOT_FOUND",tenant=""})") == 1;
  }));
  const Exposition after = scrape();
  EXPECT_EQ(after.at(R"(lipsyncd_calls_total{method="Animate",code="OK",tenant=""})"), 1);
  EXPECT_EQ(after.at(R"(lipsyncd_calls_total{method="GetModel",code="NOT_FOUND",tenant=""})"), 1);
  EXPECT_EQ(after.at(R"(lipsyncd_refusals_total{method="GetModel",code="NOT_FOUND",tenant=""})"), 1);
  EXPECT_EQ(after.value_or_zero(R"(lipsyncd_refusals_total{method="Animate",code="OK",tenant=""})"), 0);
  EXPECT_EQ(after.at("lipsyncd_phonemes_received_total"), 20);
  EXPECT_EQ(after.at(R"(lipsyncd_frames_sent_total{method="Animate"})"), produced.frames.t_us.size());
  EXPECT_EQ(after.at(R"(lipsyncd_frames_sent_total{method="Subscribe"})"), followed.frames.t_us.size());
  // Header, batches, summary.
  EXPECT_EQ(after.at(R"(lipsyncd_messages_sent_total{method="Animate"})"), produced.batches + 2);
  EXPECT_EQ(after.at(R"(lipsyncd_messages_sent_total{method="Subscribe"})"), followed.batches + 2);
  EXPECT_EQ(after.at("lipsyncd_write_latency_seconds_count"), produced.batches + 2 + followed.batches + 2);
  EXPECT_EQ(after.at(R"(lipsyncd_write_latency_seconds_bucket{le="+Inf"})"),
            after.at("lipsyncd_write_latency_seconds_count"));
  EXPECT_GT(after.at("lipsyncd_write_latency_seconds_sum"), 0);
  EXPECT_EQ(after.at(R"(lipsyncd_streams{method="Animate",state="open",tenant=""})"), 0);
  EXPECT_EQ(after.at(R"(lipsyncd_sessions{state="ended",tenant=""})"), 1);
  EXPECT_EQ(after.at("lipsyncd_calls_in_progress"), 0);
  EXPECT_EQ(after.at("lipsyncd_queued_messages"), 0);
  EXPECT_EQ(after.family_types.at("lipsyncd_face_solver_seconds"), "histogram");
}

// With --api-keys, each call is counted (and logged) under the tenant of its key; a call refused
// before a key is known has the tenant "".
class TenantMetricsTest : public LiveServerTest {
 protected:
  void SetUp() override {
    lipsync::testing::write_text(key_file_, R"({"tenants": {"studio": {}}, "keys": [{"tenant": "studio", "sha256": ")" +
                                                sha256_hex("studio-key") + R"("}]})");
    ServerConfig config;
    config.metrics_listen = "127.0.0.1:0";
    config.api_keys = key_file_.string();
    start(config);
  }
  std::filesystem::path key_file_ = lipsync::testing::make_temp_dir("lipsync-metrics-keys-") / "keys.json";
};

TEST_F(TenantMetricsTest, CallsAreCountedUnderTheTenantOfTheirKey) {
  v1::ListModelsResponse models;
  grpc::ClientContext with_key;
  with_key.AddMetadata("authorization", "Bearer studio-key");
  ASSERT_TRUE(stub_->ListModels(&with_key, {}, &models).ok());
  grpc::ClientContext without_key;
  EXPECT_EQ(stub_->ListModels(&without_key, {}, &models).error_code(), grpc::StatusCode::UNAUTHENTICATED);
  ASSERT_TRUE(eventually([&] {
    int status = 0;
    const Exposition now = parse_exposition(http_get(server_->metrics_address(), "/metrics", &status));
    return now.value_or_zero(R"(lipsyncd_calls_total{method="ListModels",code="OK",tenant="studio"})") == 1 &&
           now.value_or_zero(R"(lipsyncd_refusals_total{method="ListModels",code="UNAUTHENTICATED",tenant=""})") == 1;
  }));
}

TEST_F(MetricsTest, OtherPathsAre404) {
  int status = 0;
  http_get(server_->metrics_address(), "/", &status);
  EXPECT_EQ(status, 404);
}

TEST_F(MetricsTest, TheGrafanaDashboardQueriesOnlyExportedMetrics) {
  std::ifstream file(LIPSYNC_SOURCE_DIR "/deploy/grafana/lipsyncd.json");
  ASSERT_TRUE(file) << "deploy/grafana/lipsyncd.json";
  const nlohmann::json dashboard = nlohmann::json::parse(file);
  std::vector<std::string> expressions;
  const std::function<void(const nlohmann::json&)> collect = [&](const nlohmann::json& node) {
    if (node.is_object()) {
      for (const auto& [key, value] : node.items()) {
        if (key == "expr" && value.is_string()) expressions.push_back(value.get<std::string>());
        collect(value);
      }
    } else if (node.is_array()) {
      for (const auto& item : node) collect(item);
    }
  };
  collect(dashboard);
  ASSERT_GE(expressions.size(), 8u);
  const Exposition exported = scrape();
  const std::regex metric(R"(lipsyncd_[a-z_]+)");
  for (const std::string& expression : expressions) {
    std::set<std::string> named;
    for (std::sregex_iterator it(expression.begin(), expression.end(), metric), end; it != end; ++it) {
      std::string name = it->str();
      for (const std::string suffix : {"_bucket", "_sum", "_count"}) {
        if (!exported.family_types.count(name) && name.ends_with(suffix)) name.resize(name.size() - suffix.size());
      }
      named.insert(name);
    }
    EXPECT_FALSE(named.empty()) << "no lipsyncd metric in: " << expression;
    for (const std::string& name : named) {
      EXPECT_TRUE(exported.family_types.count(name)) << name << " (in " << expression << ") is not exported";
    }
  }
}

}  // namespace
}  // namespace lipsync::server
