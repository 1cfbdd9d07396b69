// Several replicas behind a session-aware load balancer, all real: three lipsyncd processes and
// Debian's nginx with deploy/nginx/lipsyncd.conf (its replica list and port replaced), on
// 127.0.0.1. Clients use the C++ client library, which sends x-lipsync-session by itself.
//   - sessions, each with a producer and three subscribers, spread over the replicas and every
//     subscriber gets exactly its producer's frames;
//   - a replica killed with SIGKILL mid-stream fails its sessions with an error status while the
//     others finish untouched, and new sessions go to the survivors;
//   - a replica stopped with SIGTERM drains its streams to the end, and sessions started during
//     the drain succeed on another replica.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <thread>

#include "../support/child_process.hpp"
#include "lipsync/client/animation_client.hpp"
#include "lipsync/synthetic.hpp"

namespace lipsync {
namespace {

using client::AnimationClient;
using client::ReceivedTrack;

int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof(address);
  ::bind(fd, reinterpret_cast<sockaddr*>(&address), size);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size);
  ::close(fd);
  return ntohs(address.sin_port);
}

std::vector<v1::Phoneme> phonemes(std::uint64_t seed) {
  std::vector<v1::Phoneme> out;
  for (const auto& interval : synthesize_utterance({.phonemes = 24, .seed = seed})) {
    v1::Phoneme phoneme;
    phoneme.set_label(interval.label);
    phoneme.set_start_us(interval.start_us);
    phoneme.set_end_us(interval.end_us);
    out.push_back(phoneme);
  }
  return out;
}

/// What one stream received, filled on gRPC's threads.
struct Collected {
  std::mutex mutex;
  ReceivedTrack track;
  bool header = false;
  void add(const v1::TrackMessage& message) {
    std::lock_guard lock(mutex);
    try {
      track.add(message);
      header = header || message.has_header();
    } catch (const std::exception&) {
    }
  }
};

/// A session through the balancer: a producer that has sent its first half and three
/// subscribers attached from the beginning.
struct Session {
  Session(const AnimationClient& client, std::string name_in, std::uint64_t seed)
      : name(std::move(name_in)), input(phonemes(seed)) {
    v1::AnimationSettings settings;
    settings.set_session(name);
    producer = client.start_animate(settings, [this](const v1::TrackMessage& m) { produced.add(m); });
    const auto half = std::vector<v1::Phoneme>(input.begin(), input.begin() + 12);
    producer->send(half);
    for (int i = 0; i < 100 && !header(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
    for (auto& subscriber : followed) {
      subscriber.call = client.start_subscribe(name, v1::SubscribeRequest::START_FROM_BEGINNING,
                                               [&subscriber](const v1::TrackMessage& m) { subscriber.got.add(m); });
    }
  }
  bool header() {
    std::lock_guard lock(produced.mutex);
    return produced.header;
  }
  void finish() {
    producer->send(std::vector<v1::Phoneme>(input.begin() + 12, input.end()));
    producer->end();
  }
  /// "" when producer and subscribers ended OK with the same frames; else what went wrong.
  std::string check() {
    const grpc::Status status = producer->wait();
    if (!status.ok()) return name + ": producer " + status.error_message();
    for (auto& subscriber : followed) {
      const grpc::Status sub = subscriber.call->wait();
      if (!sub.ok()) return name + ": subscriber " + sub.error_message();
      if (subscriber.got.track.track.t_us != produced.track.track.t_us ||
          subscriber.got.track.track.values != produced.track.track.values || produced.track.track.t_us.empty()) {
        return name + ": a subscriber's frames differ from the producer's";
      }
    }
    return "";
  }
  struct Follower {
    std::unique_ptr<client::SubscribeCall> call;
    Collected got;
  };
  std::string name;
  std::vector<v1::Phoneme> input;
  Collected produced;
  std::unique_ptr<client::AnimateCall> producer;
  std::array<Follower, 3> followed;
};

class BalancerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!std::filesystem::exists(kNginx)) GTEST_SKIP() << kNginx << " is missing: apt-get install nginx";
    dir_ = testing::make_temp_dir("lipsync-balancer-");
    std::string servers;
    for (int i = 0; i < 3; ++i) {
      const auto out = dir_ / ("replica" + std::to_string(i) + ".out");
      replicas_.push_back(std::make_unique<testing::ChildProcess>(
          std::vector<std::string>{LIPSYNCD_PATH, "--listen", "127.0.0.1:0", "--replica-name", "r" + std::to_string(i),
                                   "--drain-deadline-ms", "30000", "--log-level", "info"},
          dir_, out, dir_ / ("replica" + std::to_string(i) + ".err")));
      addresses_.push_back(testing::wait_for_listening_address(out));
      ASSERT_FALSE(addresses_.back().empty());
      servers += "    server " + addresses_.back() + " max_fails=1 fail_timeout=10s;\n";
    }
    // The shipped configuration, with this test's replicas and port.
    std::string site = testing::read_text(std::filesystem::path(LIPSYNC_SOURCE_DIR) / "deploy/nginx/lipsyncd.conf");
    site = std::regex_replace(site, std::regex(R"((    server 127\.0\.0\.1:5005[1-3][^\n]*\n)+)"), servers);
    const int port = free_port();
    site = std::regex_replace(site, std::regex(R"(listen 50050 http2;)"),
                              "listen 127.0.0.1:" + std::to_string(port) + " http2;");
    ASSERT_NE(site.find(servers), std::string::npos);
    testing::write_text(dir_ / "lipsyncd.conf", site);
    testing::write_text(dir_ / "nginx.conf",
                        "worker_processes 1;\npid " + (dir_ / "nginx.pid").string() + ";\nerror_log " +
                            (dir_ / "nginx.log").string() +
                            " info;\nevents { worker_connections 4096; }\nhttp {\n  access_log off;\n"
                            "  client_body_temp_path " +
                            dir_.string() + ";\n  include " + (dir_ / "lipsyncd.conf").string() + ";\n}\n");
    nginx_ = std::make_unique<testing::ChildProcess>(
        std::vector<std::string>{kNginx, "-p", dir_.string(), "-c", (dir_ / "nginx.conf").string(), "-g",
                                 "daemon off;"},
        dir_, dir_ / "nginx.out", dir_ / "nginx.err");
    balancer_ = "127.0.0.1:" + std::to_string(port);
    client_ = std::make_unique<AnimationClient>(balancer_);
    client_->wait_connected();
  }
  void TearDown() override {
    if (HasFailure()) {
      std::cerr << "nginx:\n" << testing::read_text(dir_ / "nginx.log");
      for (int i = 0; i < 3; ++i) {
        std::cerr << "replica r" << i << ":\n" << testing::read_text(dir_ / ("replica" + std::to_string(i) + ".err"));
      }
    }
    nginx_.reset();
    replicas_.clear();
    if (!dir_.empty()) std::filesystem::remove_all(dir_);
  }

  /// Which replica holds `session` (asked directly; -1 when none does).
  int holder(const std::string& session) {
    for (std::size_t i = 0; i < addresses_.size(); ++i) {
      if (addresses_[i].empty()) continue;
      client::ClientOptions quick;
      quick.connect_timeout = std::chrono::milliseconds(500);
      quick.unary_timeout = std::chrono::milliseconds(500);
      quick.stream_timeout = std::chrono::milliseconds(2000);
      AnimationClient direct(addresses_[i], quick);
      Collected got;
      auto call = direct.start_subscribe(session, v1::SubscribeRequest::START_FROM_BEGINNING,
                                         [&got](const v1::TrackMessage& m) { got.add(m); });
      for (int wait = 0; wait < 100; ++wait) {
        {
          std::lock_guard lock(got.mutex);
          if (got.header) return static_cast<int>(i);  // attached: the session is held there
        }
        if (call->done()) break;  // NOT_FOUND
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
      }
    }
    return -1;
  }

  /// The replica holding each session.
  std::vector<int> holders(const std::vector<std::unique_ptr<Session>>& sessions) {
    std::vector<int> held;
    for (const auto& session : sessions) held.push_back(holder(session->name));
    return held;
  }
  /// The replica that holds the most of `held`.
  static int busiest(const std::vector<int>& held) {
    std::map<int, int> count;
    for (const int replica : held) ++count[replica];
    return std::max_element(count.begin(), count.end(), [](auto& a, auto& b) { return a.second < b.second; })->first;
  }

  std::vector<std::unique_ptr<Session>> open(const std::string& prefix, int count, std::uint64_t seed) {
    std::vector<std::unique_ptr<Session>> sessions;
    for (int i = 0; i < count; ++i) {
      sessions.push_back(std::make_unique<Session>(*client_, prefix + std::to_string(i), seed + i));
    }
    return sessions;
  }

  static constexpr const char* kNginx = "/usr/sbin/nginx";
  std::filesystem::path dir_;
  std::vector<std::unique_ptr<testing::ChildProcess>> replicas_;
  std::vector<std::string> addresses_;
  std::unique_ptr<testing::ChildProcess> nginx_;
  std::string balancer_;
  std::unique_ptr<AnimationClient> client_;
};

TEST_F(BalancerTest, SessionsSpreadOverTheReplicasAndEverySubscriberGetsItsProducersFrames) {
  auto sessions = open("spread-", 50, 100);
  std::map<int, int> per_replica;
  for (auto& session : sessions) ++per_replica[holder(session->name)];
  for (auto& session : sessions) session->finish();
  for (auto& session : sessions) EXPECT_EQ(session->check(), "");
  EXPECT_EQ(per_replica.count(-1), 0u);
  EXPECT_EQ(per_replica.size(), 3u) << "sessions per replica: r0 " << per_replica[0] << ", r1 " << per_replica[1]
                                    << ", r2 " << per_replica[2];
}

TEST_F(BalancerTest, AKilledReplicaFailsItsSessionsClearlyAndTheOthersFinish) {
  auto sessions = open("kill-", 12, 200);
  const std::vector<int> held = holders(sessions);
  const int victim = busiest(held);
  ASSERT_GE(victim, 0);
  replicas_[victim]->signal(SIGKILL);
  replicas_[victim]->wait();
  addresses_[victim].clear();
  for (auto& session : sessions) session->finish();
  for (std::size_t i = 0; i < sessions.size(); ++i) {
    if (held[i] == victim) {
      const grpc::Status status = sessions[i]->producer->wait();
      EXPECT_FALSE(status.ok()) << sessions[i]->name << " survived the death of its replica";
      for (auto& subscriber : sessions[i]->followed) EXPECT_FALSE(subscriber.call->wait().ok());
    } else {
      EXPECT_EQ(sessions[i]->check(), "") << "on replica r" << held[i];
    }
  }
  auto after = open("after-kill-", 20, 300);
  for (auto& session : after) session->finish();
  for (auto& session : after) EXPECT_EQ(session->check(), "");
}

TEST_F(BalancerTest, ATerminatedReplicaDrainsItsStreamsWhileNewSessionsSucceedElsewhere) {
  auto sessions = open("drain-", 9, 400);
  const std::vector<int> held = holders(sessions);
  const int draining = busiest(held);
  ASSERT_GE(draining, 0);
  replicas_[draining]->terminate();
  ASSERT_TRUE(testing::wait_for_text(dir_ / ("replica" + std::to_string(draining) + ".err"), "listener closed"))
      << "the drain has not begun";
  auto during = open("during-drain-", 20, 500);  // some of these hash to the draining replica
  for (auto& session : during) session->finish();
  for (auto& session : during) EXPECT_EQ(session->check(), "");
  // nginx tried the draining replica for some of them, was refused, and went on to another.
  EXPECT_THAT(testing::read_text(dir_ / "nginx.log"),
              ::testing::HasSubstr("connect() failed (111: Connection refused) while connecting to upstream"));
  for (auto& session : sessions) session->finish();
  for (std::size_t i = 0; i < sessions.size(); ++i) EXPECT_EQ(sessions[i]->check(), "") << "on r" << held[i];
  EXPECT_EQ(replicas_[draining]->wait(), 0);
}

}  // namespace
}  // namespace lipsync
