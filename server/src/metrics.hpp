// lipsyncd's metrics: counters, gauges and histograms with labels, written in
// the Prometheus text exposition format (version 0.0.4) for GET /metrics
// (metrics_http.hpp).
//
// The hot path only touches atomics: a call looks up its labelled series once
// (a short lock, when it starts) and keeps the pointer; adding to a counter or
// observing a histogram is a relaxed atomic add. Gauges that the server already
// knows (open streams, sessions by state, queue depths) are read when scraped.
// Series live as long as the registry (label values are few: methods, status
// codes, states, the tenants of the key file), so pointers stay valid.
//
// The metric names are the contract with dashboards (deploy/grafana/lipsyncd.json,
// docs/server.md "Metrics"); ServerMetrics below declares every one of them.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace lipsync::server {

using LabelValues = std::vector<std::string>;

class Counter {
 public:
  void add(std::uint64_t amount = 1) { value_.fetch_add(amount, std::memory_order_relaxed); }
  std::uint64_t value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::uint64_t> value_{0};
};

/// A count that goes up and down (open streams): read by a gauge when scraped.
class Level {
 public:
  void add(std::int64_t amount) { value_.fetch_add(amount, std::memory_order_relaxed); }
  std::int64_t value() const { return value_.load(std::memory_order_relaxed); }

 private:
  std::atomic<std::int64_t> value_{0};
};

/// Cumulative buckets over fixed upper bounds in seconds; observations in microseconds.
class Histogram {
 public:
  explicit Histogram(const std::vector<double>& bounds_s);
  void observe_us(std::int64_t duration_us);

  struct Snapshot {
    std::vector<double> bounds_s;
    std::vector<std::uint64_t> cumulative;  ///< per bound, then +Inf
    std::uint64_t count = 0;
    double sum_s = 0;
  };
  Snapshot snapshot() const;

 private:
  std::vector<std::int64_t> bounds_us_;
  std::vector<double> bounds_s_;
  std::unique_ptr<std::atomic<std::uint64_t>[]> buckets_;  // per bound, then +Inf (not cumulative)
  std::atomic<std::uint64_t> count_{0};
  std::atomic<std::int64_t> sum_us_{0};
};

/// One metric name with its label names; a series per set of label values.
template <class Series>
class Family {
 public:
  Family(std::string name, std::string help, std::vector<std::string> label_names,
         std::function<std::unique_ptr<Series>()> make)
      : name_(std::move(name)), help_(std::move(help)), label_names_(std::move(label_names)), make_(std::move(make)) {}

  /// The series for `values` (one per label name), made on first use. Keep the reference.
  Series& with(const LabelValues& values) {
    std::lock_guard lock(mutex_);
    auto& series = series_[values];
    if (!series) series = make_();
    return *series;
  }
  /// Calls `visit(values, series)` for each series, in label order.
  template <class Visit>
  void each(Visit&& visit) const {
    std::lock_guard lock(mutex_);
    for (const auto& [values, series] : series_) visit(values, *series);
  }
  const std::string& name() const { return name_; }
  const std::string& help() const { return help_; }
  const std::vector<std::string>& label_names() const { return label_names_; }

 private:
  std::string name_;
  std::string help_;
  std::vector<std::string> label_names_;
  std::function<std::unique_ptr<Series>()> make_;
  mutable std::mutex mutex_;
  std::map<LabelValues, std::unique_ptr<Series>> series_;
};

/// A gauge read when scraped: its series and values.
struct GaugeSample {
  LabelValues labels;
  double value = 0;
};
struct Gauge {
  std::string name;
  std::string help;
  std::vector<std::string> label_names;
  std::function<std::vector<GaugeSample>()> sample;
};

class MetricsRegistry {
 public:
  Family<Counter>& counter(std::string name, std::string help, std::vector<std::string> label_names);
  Family<Histogram>& histogram(std::string name, std::string help, std::vector<std::string> label_names,
                               const std::vector<double>& bounds_s);
  void gauge(Gauge gauge);

  /// Everything, in the Prometheus text format.
  std::string exposition() const;

 private:
  mutable std::mutex mutex_;
  std::vector<std::unique_ptr<Family<Counter>>> counters_;
  std::vector<std::unique_ptr<Family<Histogram>>> histograms_;
  std::vector<Gauge> gauges_;
};

/// The series lipsyncd exports (names in docs/server.md, "Metrics").
struct ServerMetrics {
  explicit ServerMetrics(MetricsRegistry& registry);

  MetricsRegistry& registry;
  Family<Counter>& calls;          ///< lipsyncd_calls_total{method,code,tenant}: calls ended, by status
  Family<Counter>& refusals;       ///< lipsyncd_refusals_total{method,code,tenant}: ended with an error status of ours
  Family<Counter>& frames_sent;    ///< lipsyncd_frames_sent_total{method}
  Family<Counter>& messages_sent;  ///< lipsyncd_messages_sent_total{method}
  Counter& phonemes_received;      ///< lipsyncd_phonemes_received_total
  /// lipsyncd_listen_decoders_total{loaded}: live streams' decoders, loaded "ahead" (a spare) or
  /// "by_stream" (none was ready)
  Family<Counter>& listen_decoders;
  Histogram& write_latency;                      ///< lipsyncd_write_latency_seconds: computable → written
  Histogram& face_solver;                        ///< lipsyncd_face_solver_seconds: per mesh frame batch
  std::atomic<std::int64_t> queued_messages{0};  ///< lipsyncd_queued_messages (gauge)
  /// lipsyncd_streams{method,state="open",tenant}: a stream counts once authenticated, until OnDone.
  Family<Level> open_streams{"lipsyncd_streams", "", {"method", "tenant"}, [] { return std::make_unique<Level>(); }};
};

}  // namespace lipsync::server
