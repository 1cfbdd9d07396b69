// Viseme writers (layouts and examples: docs/output-formats.md, "Visemes").
//
// Times: the lipsync-visemes JSON carries the exact integer microseconds (`t_us`, `start_us`) with
// the same time as seconds with 6 decimals; Azure's AudioOffset is in 100-ns ticks, so 10 × µs is
// exact. Polly speech marks are whole milliseconds (rounded half up from µs) and Rhubarb's times are
// centiseconds written as seconds with 2 decimals (cue starts rounded half up, the end truncated,
// as Rhubarb truncates its duration): both formats allow nothing finer.
#include "lipsync/viseme_writer.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>
#include <string>

#include "lipsync/time.hpp"

namespace lipsync {
namespace {

void put_integer(std::string& text, std::int64_t value) {
  char digits[24];
  const auto result = std::to_chars(std::begin(digits), std::end(digits), value);
  text.append(digits, result.ptr);
}

void put_float(std::string& text, float value) {
  if (!std::isfinite(value)) {
    text.append("null");
    return;
  }
  char digits[32];
  const auto result = std::to_chars(std::begin(digits), std::end(digits), value);
  text.append(digits, result.ptr);
}

/// Viseme names are ours (letters, digits, '@'): no JSON escaping needed, but keep it safe.
void put_json_string(std::string& text, std::string_view value) {
  text.push_back('"');
  for (const char ch : value) {
    if (ch == '"' || ch == '\\') text.push_back('\\');
    text.push_back(ch);
  }
  text.push_back('"');
}

/// Centiseconds as Rhubarb writes seconds: "12.34".
void put_centiseconds(std::string& text, std::int64_t cs) {
  put_integer(text, cs / 100);
  text.push_back('.');
  if (cs % 100 < 10) text.push_back('0');
  put_integer(text, cs % 100);
}

void flush(std::string& text, std::ostream& out) {
  out.write(text.data(), static_cast<std::streamsize>(text.size()));
  text.clear();
}

constexpr std::size_t kFlushBytes = std::size_t{64} * 1024;

void write_lipsync_visemes(const VisemeTrackView& view, std::ostream& out) {
  const Track& track = view.track;
  const VisemeTrack& visemes = view.visemes;
  const auto& names = view.classifier.names();
  const bool azure = view.classifier.options().vocabulary == VisemeVocabulary::azure;
  std::string text;
  text.append("{\"format\":\"lipsync-visemes\",\"version\":1,\"model\":");
  put_json_string(text, view.model);
  text.append(",\"vocabulary\":");
  put_json_string(text, to_string(view.classifier.options().vocabulary));
  text.append(",\"fps\":");
  put_integer(text, track.fps);
  text.append(",\"end_us\":");
  put_integer(text, view.end_us);
  text.append(",\n\"visemes\":[");
  for (std::size_t v = 0; v < names.size(); ++v) {
    if (v > 0) text.push_back(',');
    put_json_string(text, names[v]);
  }
  text.append("],\n\"frames\":[");
  for (std::size_t f = 0; f < track.frame_count(); ++f) {
    text.append(f == 0 ? "\n{\"t\":" : ",\n{\"t\":");
    text.append(format_seconds(track.t_us[f]));
    text.append(",\"t_us\":");
    put_integer(text, track.t_us[f]);
    text.append(",\"kind\":\"");
    text.append(to_string(track.kinds[f]));
    text.append("\",\"viseme\":");
    put_integer(text, visemes.winners[f]);
    text.append(",\"weights\":[");
    for (std::size_t v = 0; v < visemes.viseme_count; ++v) {
      if (v > 0) text.push_back(',');
      put_float(text, visemes.weights[f * visemes.viseme_count + v]);
    }
    text.append("]}");
    if (text.size() >= kFlushBytes) flush(text, out);
  }
  text.append("\n],\n\"events\":[");
  for (std::size_t e = 0; e < visemes.events.size(); ++e) {
    const VisemeEvent& event = visemes.events[e];
    text.append(e == 0 ? "\n{\"viseme\":" : ",\n{\"viseme\":");
    put_integer(text, event.viseme);
    text.append(",\"name\":");
    put_json_string(text, names[event.viseme]);
    text.append(",\"start_us\":");
    put_integer(text, event.start_us);
    text.append(",\"t\":");
    text.append(format_seconds(event.start_us));
    if (azure) {
      text.append(",\"audio_offset_ticks\":");
      put_integer(text, event.start_us * 10);
    }
    text.append("}");
    if (text.size() >= kFlushBytes) flush(text, out);
  }
  text.append("\n]}\n");
  flush(text, out);
}

void write_polly(const VisemeTrackView& view, std::ostream& out) {
  const auto& names = view.classifier.names();
  std::string text;
  for (const VisemeEvent& event : view.visemes.events) {
    text.append("{\"time\":");
    put_integer(text, (event.start_us + 500) / 1000);
    text.append(",\"type\":\"viseme\",\"value\":");
    put_json_string(text, names[event.viseme]);
    text.append("}\n");
    if (text.size() >= kFlushBytes) flush(text, out);
  }
  flush(text, out);
}

std::string_view rhubarb_rest(const VisemeClassifier& classifier) { return classifier.names()[classifier.silence()]; }

void write_rhubarb_tsv(const VisemeTrackView& view, std::ostream& out) {
  std::string text;
  for (const RhubarbCue& cue : rhubarb_cues(view.classifier, view.visemes.events, view.end_us)) {
    put_centiseconds(text, cue.start_cs);
    text.push_back('\t');
    text.append(cue.shape);
    text.push_back('\n');
    if (text.size() >= kFlushBytes) flush(text, out);
  }
  // Rhubarb's last line: the end of the recording, truncated to 0.01 s, with the closed mouth.
  put_centiseconds(text, view.end_us / 10'000);
  text.push_back('\t');
  text.append(rhubarb_rest(view.classifier));
  text.push_back('\n');
  flush(text, out);
}

void write_rhubarb_json(const VisemeTrackView& view, std::ostream& out) {
  const std::int64_t end_cs = view.end_us / 10'000;
  const auto cues = rhubarb_cues(view.classifier, view.visemes.events, view.end_us);
  std::string text;
  text.append("{\n  \"metadata\": {\n    \"soundFile\": \"\",\n    \"duration\": ");
  put_centiseconds(text, end_cs);
  text.append("\n  },\n  \"mouthCues\": [\n");
  for (std::size_t i = 0; i < cues.size(); ++i) {
    text.append("    { \"start\": ");
    put_centiseconds(text, cues[i].start_cs);
    text.append(", \"end\": ");
    put_centiseconds(text, i + 1 < cues.size() ? cues[i + 1].start_cs : end_cs);
    text.append(", \"value\": ");
    put_json_string(text, cues[i].shape);
    text.append(i + 1 < cues.size() ? " },\n" : " }\n");
    if (text.size() >= kFlushBytes) flush(text, out);
  }
  text.append("  ]\n}\n");
  flush(text, out);
}

}  // namespace

std::string_view to_string(VisemeFormat format) { return name_of(kVisemeFormats, format); }

std::optional<VisemeFormat> viseme_format_from_string(std::string_view name) {
  return format_named(kVisemeFormats, name);
}

VisemeVocabulary vocabulary_of(VisemeFormat format) {
  switch (format) {
    case VisemeFormat::oculus:
      return VisemeVocabulary::oculus;
    case VisemeFormat::azure:
      return VisemeVocabulary::azure;
    case VisemeFormat::polly:
      return VisemeVocabulary::polly;
    case VisemeFormat::rhubarb_tsv:
    case VisemeFormat::rhubarb_json:
      return VisemeVocabulary::rhubarb;
  }
  return VisemeVocabulary::oculus;
}

std::vector<RhubarbCue> rhubarb_cues(const VisemeClassifier& classifier, const std::vector<VisemeEvent>& events,
                                     std::int64_t end_us) {
  const auto& names = classifier.names();
  const std::int64_t end_cs = end_us / 10'000;
  std::vector<RhubarbCue> cues;
  for (const VisemeEvent& event : events) {
    const std::int64_t start_cs = (event.start_us + 5'000) / 10'000;
    if (start_cs >= end_cs) break;
    const RhubarbCue cue{start_cs, names[event.viseme]};
    if (!cues.empty() && cues.back().start_cs == start_cs) cues.pop_back();  // the later event wins
    if (!cues.empty() && cues.back().shape == cue.shape) continue;           // nothing changes
    cues.push_back(cue);
  }
  if (cues.empty() || cues.front().start_cs > 0) {
    cues.insert(cues.begin(), RhubarbCue{0, rhubarb_rest(classifier)});
    if (cues.size() > 1 && cues[1].shape == cues[0].shape) cues.erase(cues.begin() + 1);
  }
  return cues;
}

void write_visemes(const VisemeTrackView& view, VisemeFormat format, std::ostream& out) {
  if (view.classifier.options().vocabulary != vocabulary_of(format)) {
    throw std::invalid_argument(std::string(to_string(format)) + " needs " +
                                std::string(to_string(vocabulary_of(format))) + " visemes, got " +
                                std::string(to_string(view.classifier.options().vocabulary)));
  }
  const std::size_t frames = view.track.frame_count();
  if (view.visemes.viseme_count != view.classifier.viseme_count() || view.visemes.winners.size() != frames ||
      view.visemes.weights.size() != frames * view.visemes.viseme_count || view.track.kinds.size() != frames) {
    throw std::invalid_argument("viseme track disagrees with its track: " + std::to_string(frames) + " frames, " +
                                std::to_string(view.visemes.winners.size()) + " winners, " +
                                std::to_string(view.visemes.weights.size()) + " weights");
  }
  switch (format) {
    case VisemeFormat::oculus:
    case VisemeFormat::azure:
      write_lipsync_visemes(view, out);
      return;
    case VisemeFormat::polly:
      write_polly(view, out);
      return;
    case VisemeFormat::rhubarb_tsv:
      write_rhubarb_tsv(view, out);
      return;
    case VisemeFormat::rhubarb_json:
      write_rhubarb_json(view, out);
      return;
  }
}

}  // namespace lipsync
