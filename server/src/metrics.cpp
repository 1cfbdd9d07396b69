// The metrics registry and its text exposition (metrics.hpp). Label values are
// escaped as the format asks (backslash, double quote, newline); numbers are
// written in their shortest exact form.
#include "metrics.hpp"

#include <array>
#include <charconv>

namespace lipsync::server {
namespace {

std::string number(double value) {
  std::array<char, 32> text{};
  const auto result = std::to_chars(text.data(), text.data() + text.size(), value);
  return std::string(text.data(), result.ptr);
}

std::string escaped_label(const std::string& value) {
  std::string out;
  for (const char c : value) {
    if (c == '\\')
      out += "\\\\";
    else if (c == '"')
      out += "\\\"";
    else if (c == '\n')
      out += "\\n";
    else
      out += c;
  }
  return out;
}

/// {a="x",b="y"} (with `extra` appended, e.g. le="0.1"); "" without labels.
std::string labels(const std::vector<std::string>& names, const LabelValues& values, const std::string& extra = {}) {
  std::string out;
  for (std::size_t i = 0; i < names.size() && i < values.size(); ++i) {
    out += (out.empty() ? "" : ",") + names[i] + "=\"" + escaped_label(values[i]) + "\"";
  }
  if (!extra.empty()) out += (out.empty() ? "" : ",") + extra;
  return out.empty() ? out : "{" + out + "}";
}

void header(std::string& out, const std::string& name, const std::string& help, const char* type) {
  out += "# HELP " + name + " " + help + "\n# TYPE " + name + " " + type + "\n";
}

}  // namespace

Histogram::Histogram(const std::vector<double>& bounds_s)
    : bounds_s_(bounds_s), buckets_(std::make_unique<std::atomic<std::uint64_t>[]>(bounds_s.size() + 1)) {
  for (const double bound : bounds_s) bounds_us_.push_back(static_cast<std::int64_t>(bound * 1e6));
}

void Histogram::observe_us(std::int64_t duration_us) {
  std::size_t bucket = 0;
  while (bucket < bounds_us_.size() && duration_us > bounds_us_[bucket]) ++bucket;
  buckets_[bucket].fetch_add(1, std::memory_order_relaxed);
  sum_us_.fetch_add(duration_us, std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
}

Histogram::Snapshot Histogram::snapshot() const {
  Snapshot snapshot;
  snapshot.bounds_s = bounds_s_;
  std::uint64_t running = 0;
  for (std::size_t i = 0; i <= bounds_s_.size(); ++i) {
    running += buckets_[i].load(std::memory_order_relaxed);
    snapshot.cumulative.push_back(running);
  }
  snapshot.count = running;  // consistent with the buckets even while observations land
  snapshot.sum_s = static_cast<double>(sum_us_.load(std::memory_order_relaxed)) / 1e6;
  return snapshot;
}

Family<Counter>& MetricsRegistry::counter(std::string name, std::string help, std::vector<std::string> label_names) {
  std::lock_guard lock(mutex_);
  counters_.push_back(std::make_unique<Family<Counter>>(std::move(name), std::move(help), std::move(label_names),
                                                        [] { return std::make_unique<Counter>(); }));
  return *counters_.back();
}

Family<Histogram>& MetricsRegistry::histogram(std::string name, std::string help, std::vector<std::string> label_names,
                                              const std::vector<double>& bounds_s) {
  std::lock_guard lock(mutex_);
  histograms_.push_back(
      std::make_unique<Family<Histogram>>(std::move(name), std::move(help), std::move(label_names),
                                          [bounds_s] { return std::make_unique<Histogram>(bounds_s); }));
  return *histograms_.back();
}

void MetricsRegistry::gauge(Gauge gauge) {
  std::lock_guard lock(mutex_);
  gauges_.push_back(std::move(gauge));
}

std::string MetricsRegistry::exposition() const {
  std::lock_guard lock(mutex_);
  std::string out;
  for (const auto& family : counters_) {
    header(out, family->name(), family->help(), "counter");
    family->each([&](const LabelValues& values, const Counter& counter) {
      out += family->name() + labels(family->label_names(), values) + " " + std::to_string(counter.value()) + "\n";
    });
  }
  for (const Gauge& gauge : gauges_) {
    header(out, gauge.name, gauge.help, "gauge");
    for (const GaugeSample& sample : gauge.sample()) {
      out += gauge.name + labels(gauge.label_names, sample.labels) + " " + number(sample.value) + "\n";
    }
  }
  for (const auto& family : histograms_) {
    const std::string& name = family->name();
    header(out, name, family->help(), "histogram");
    family->each([&](const LabelValues& values, const Histogram& histogram) {
      const Histogram::Snapshot snapshot = histogram.snapshot();
      for (std::size_t i = 0; i < snapshot.cumulative.size(); ++i) {
        const std::string le = i < snapshot.bounds_s.size() ? number(snapshot.bounds_s[i]) : "+Inf";
        out += name + "_bucket" + labels(family->label_names(), values, "le=\"" + le + "\"") + " " +
               std::to_string(snapshot.cumulative[i]) + "\n";
      }
      out += name + "_sum" + labels(family->label_names(), values) + " " + number(snapshot.sum_s) + "\n";
      out += name + "_count" + labels(family->label_names(), values) + " " + std::to_string(snapshot.count) + "\n";
    });
  }
  return out;
}

namespace {

// From 100 µs to 10 s: a frame written at once is well under a millisecond; a held-back
// producer or a subscriber behind a slow link takes seconds.
const std::vector<double> kLatencyBoundsSeconds = {0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025,
                                                   0.05,   0.1,     0.25,   0.5,   1,      2.5,   5,    10};

}  // namespace

ServerMetrics::ServerMetrics(MetricsRegistry& registry_in)
    : registry(registry_in),
      calls(registry.counter("lipsyncd_calls_total", "Calls ended, by method and final status code.",
                             {"method", "code", "tenant"})),
      refusals(registry.counter("lipsyncd_refusals_total",
                                "Calls the server ended with an error status (not OK, not CANCELLED), by method "
                                "and status code: the reason.",
                                {"method", "code", "tenant"})),
      frames_sent(registry.counter("lipsyncd_frames_sent_total", "Animation frames sent, by method.", {"method"})),
      messages_sent(
          registry.counter("lipsyncd_messages_sent_total", "Messages written to streams, by method.", {"method"})),
      phonemes_received(
          registry.counter("lipsyncd_phonemes_received_total", "Phonemes received by Animate and Render.", {})
              .with({})),
      listen_decoders(registry.counter("lipsyncd_listen_decoders_total",
                                       "Live Listen streams' recognisers, by where their decoder was loaded: "
                                       "ahead (a spare, ready) or by_stream (none was ready; the stream's first "
                                       "frames wait for it).",
                                       {"loaded"})),
      write_latency(registry
                        .histogram("lipsyncd_write_latency_seconds",
                                   "Per stream message: from computable (queued for the stream) to written "
                                   "(the write completed).",
                                   {}, kLatencyBoundsSeconds)
                        .with({})),
      face_solver(registry
                      .histogram("lipsyncd_face_solver_seconds",
                                 "Face solver time per mesh frame batch (Animate) or per mesh Render.", {},
                                 kLatencyBoundsSeconds)
                      .with({})) {}

}  // namespace lipsync::server
