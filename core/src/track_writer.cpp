// Track writers (schemas and examples: docs/output-formats.md).
//
// One writer per format, over a NamedTrackView: the names (model, channels,
// ARKit shapes) and the ARKit weights are data, so a track whose model only a
// server has is written exactly like one of a local model. The model-based
// write_track is a thin wrapper that fills the view with the model's names and
// its retargeting of every frame.
//
// Each writer streams the track into a local text buffer that is handed to the
// std::ostream in chunks of about 64 KiB, so a long track costs no per-value
// stream calls and no per-frame allocation.
//
// Numbers are written so that a reader gets exactly what we hold:
//   - times come from the integer microseconds, as "seconds with 6 decimals"
//     (format_seconds) next to the integer itself, never via a float;
//   - channel values and ARKit weights are float32 and are written with the
//     shortest text that reads back to the same float (std::to_chars).
//
// The Live Link Face CSV has its own blendshape order (JawRight before JawLeft,
// MouthRight before MouthLeft) and PascalCase names. Its columns are bound to
// the view's ARKit weights by name (PascalCase → Apple camelCase lookup in
// arkit_names), never by position, so a change of either order cannot shift a
// column; a shape the view does not name is written as 0. Its Timecode is
// HH:MM:SS:FF.sss: the frame number within the second at the track's rate,
// with the fraction for key frames between grid points.
#include "lipsync/track_writer.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "lipsync/time.hpp"

namespace lipsync {
namespace {

constexpr std::size_t kFlushBytes = std::size_t{64} * 1024;

/// Text accumulated for the stream; flushed when a record ends past kFlushBytes.
class TextBuffer {
 public:
  explicit TextBuffer(std::ostream& out) : out_(out) { text_.reserve(kFlushBytes + std::size_t{8} * 1024); }

  void put(std::string_view text) { text_.append(text); }
  void put(char ch) { text_.push_back(ch); }

  void put_integer(std::int64_t value) {
    char digits[24];
    const auto result = std::to_chars(std::begin(digits), std::end(digits), value);
    text_.append(digits, result.ptr);
  }

  /// Shortest round-trip text of a float32 ("0.5", "1e-05"); non-finite values
  /// (never produced by the renderer) as `non_finite`.
  void put_float(float value, std::string_view non_finite) {
    if (!std::isfinite(value)) {
      text_.append(non_finite);
      return;
    }
    char digits[32];
    const auto result = std::to_chars(std::begin(digits), std::end(digits), value);
    text_.append(digits, result.ptr);
  }

  /// JSON string literal with the escapes RFC 8259 requires.
  void put_json_string(std::string_view text) {
    text_.push_back('"');
    for (const char ch : text) {
      switch (ch) {
        case '"':
          text_.append("\\\"");
          break;
        case '\\':
          text_.append("\\\\");
          break;
        case '\n':
          text_.append("\\n");
          break;
        case '\r':
          text_.append("\\r");
          break;
        case '\t':
          text_.append("\\t");
          break;
        default:
          if (static_cast<unsigned char>(ch) < 0x20) {
            constexpr char kHex[] = "0123456789abcdef";
            text_.append("\\u00");
            text_.push_back(kHex[(static_cast<unsigned char>(ch) >> 4) & 0xF]);
            text_.push_back(kHex[static_cast<unsigned char>(ch) & 0xF]);
          } else {
            text_.push_back(ch);
          }
      }
    }
    text_.push_back('"');
  }

  /// CSV field, quoted (RFC 4180) only when it holds a comma, quote or line break.
  void put_csv_field(std::string_view text) {
    if (text.find_first_of(",\"\r\n") == std::string_view::npos) {
      text_.append(text);
      return;
    }
    text_.push_back('"');
    for (const char ch : text) {
      if (ch == '"') text_.push_back('"');
      text_.push_back(ch);
    }
    text_.push_back('"');
  }

  void end_record() {
    if (text_.size() >= kFlushBytes) flush();
  }

  void flush() {
    out_.write(text_.data(), static_cast<std::streamsize>(text_.size()));
    text_.clear();
  }

 private:
  std::ostream& out_;
  std::string text_;
};

/// The ARKit weights of frame `frame` of `view`, in arkit_names order.
std::span<const float> frame_arkit(const NamedTrackView& view, std::size_t frame) {
  const std::size_t count = view.arkit_names.size();
  return view.arkit.subspan(frame * count, count);
}

void write_json(const NamedTrackView& view, std::ostream& out) {
  const Track& track = view.track;
  TextBuffer buffer(out);
  buffer.put("{\"format\":\"lipsync-track\",\"version\":1,\"model\":");
  buffer.put_json_string(view.model);
  buffer.put(",\"fps\":");
  buffer.put_integer(track.fps);
  buffer.put(",\n\"channels\":[");
  for (std::size_t c = 0; c < view.channel_names.size(); ++c) {
    if (c > 0) buffer.put(',');
    buffer.put_json_string(view.channel_names[c]);
  }
  buffer.put("],\n\"arkit_names\":[");
  for (std::size_t j = 0; j < view.arkit_names.size(); ++j) {
    if (j > 0) buffer.put(',');
    buffer.put_json_string(view.arkit_names[j]);
  }
  buffer.put("],\n\"frames\":[");

  for (std::size_t f = 0; f < track.frame_count(); ++f) {
    const auto values = track.frame_values(f);
    const auto arkit = frame_arkit(view, f);
    buffer.put(f == 0 ? "\n{\"t\":" : ",\n{\"t\":");
    buffer.put(format_seconds(track.t_us[f]));
    buffer.put(",\"t_us\":");
    buffer.put_integer(track.t_us[f]);
    buffer.put(",\"kind\":\"");
    buffer.put(to_string(track.kinds[f]));
    buffer.put("\",\"values\":[");
    for (std::size_t c = 0; c < values.size(); ++c) {
      if (c > 0) buffer.put(',');
      buffer.put_float(values[c], "null");
    }
    buffer.put("],\"arkit\":[");
    for (std::size_t j = 0; j < arkit.size(); ++j) {
      if (j > 0) buffer.put(',');
      buffer.put_float(arkit[j], "null");
    }
    buffer.put("]}");
    buffer.end_record();
  }
  buffer.put("\n]}\n");
  buffer.flush();
}

void write_csv(const NamedTrackView& view, std::ostream& out) {
  const Track& track = view.track;
  TextBuffer buffer(out);
  buffer.put("t,t_us,kind");
  for (const std::string_view name : view.channel_names) {
    buffer.put(',');
    buffer.put_csv_field(name);
  }
  buffer.put('\n');
  for (std::size_t f = 0; f < track.frame_count(); ++f) {
    buffer.put(format_seconds(track.t_us[f]));
    buffer.put(',');
    buffer.put_integer(track.t_us[f]);
    buffer.put(',');
    buffer.put(to_string(track.kinds[f]));
    for (const float value : track.frame_values(f)) {
      buffer.put(',');
      buffer.put_float(value, "nan");
    }
    buffer.put('\n');
    buffer.end_record();
  }
  buffer.flush();
}

// Live Link Face blendshape columns, in the order of its CSV header.
constexpr std::array<std::string_view, 52> kLiveLinkFaceShapes = {
    "EyeBlinkLeft",
    "EyeLookDownLeft",
    "EyeLookInLeft",
    "EyeLookOutLeft",
    "EyeLookUpLeft",
    "EyeSquintLeft",
    "EyeWideLeft",
    "EyeBlinkRight",
    "EyeLookDownRight",
    "EyeLookInRight",
    "EyeLookOutRight",
    "EyeLookUpRight",
    "EyeSquintRight",
    "EyeWideRight",
    "JawForward",
    "JawRight",
    "JawLeft",
    "JawOpen",
    "MouthClose",
    "MouthFunnel",
    "MouthPucker",
    "MouthRight",
    "MouthLeft",
    "MouthSmileLeft",
    "MouthSmileRight",
    "MouthFrownLeft",
    "MouthFrownRight",
    "MouthDimpleLeft",
    "MouthDimpleRight",
    "MouthStretchLeft",
    "MouthStretchRight",
    "MouthRollLower",
    "MouthRollUpper",
    "MouthShrugLower",
    "MouthShrugUpper",
    "MouthPressLeft",
    "MouthPressRight",
    "MouthLowerDownLeft",
    "MouthLowerDownRight",
    "MouthUpperUpLeft",
    "MouthUpperUpRight",
    "BrowDownLeft",
    "BrowDownRight",
    "BrowInnerUp",
    "BrowOuterUpLeft",
    "BrowOuterUpRight",
    "CheekPuff",
    "CheekSquintLeft",
    "CheekSquintRight",
    "NoseSneerLeft",
    "NoseSneerRight",
    "TongueOut",
};

// Head and eye rotations that follow the blendshapes; lipsyncd writes 0.
constexpr std::array<std::string_view, 9> kLiveLinkFaceRotations = {
    "HeadYaw",     "HeadPitch",   "HeadRoll",      "LeftEyeYaw",   "LeftEyePitch",
    "LeftEyeRoll", "RightEyeYaw", "RightEyePitch", "RightEyeRoll",
};

constexpr std::size_t kLiveLinkFaceCount = kLiveLinkFaceShapes.size() + kLiveLinkFaceRotations.size();

/// For each Live Link Face column, the index of the same shape in `arkit_names`,
/// found by name ("JawOpen" → "jawOpen"); nullopt when it is not there.
std::array<std::optional<std::size_t>, kLiveLinkFaceShapes.size()> live_link_face_columns(
    std::span<const std::string_view> arkit_names) {
  std::array<std::optional<std::size_t>, kLiveLinkFaceShapes.size()> indices{};
  std::string apple;
  for (std::size_t i = 0; i < kLiveLinkFaceShapes.size(); ++i) {
    apple = kLiveLinkFaceShapes[i];
    apple[0] = static_cast<char>(apple[0] - 'A' + 'a');
    const auto it = std::find(arkit_names.begin(), arkit_names.end(), apple);
    if (it != arkit_names.end()) indices[i] = static_cast<std::size_t>(it - arkit_names.begin());
  }
  return indices;
}

void put_two_digits(TextBuffer& buffer, std::int64_t value) {
  if (value < 10) buffer.put('0');
  buffer.put_integer(value);
}

/// HH:MM:SS:FF.sss for `t_us` at `fps`: FF.sss is the frame position within the
/// second, rounded to 1/1000 of a frame (grid frames land exactly on .000).
void put_timecode(TextBuffer& buffer, std::int64_t t_us, int fps) {
  if (t_us < 0) {
    buffer.put('-');
    t_us = -t_us;
  }
  const std::int64_t milliframes = (t_us * fps + 500) / 1000;
  const std::int64_t frames = milliframes / 1000;
  const std::int64_t seconds = frames / fps;
  put_two_digits(buffer, seconds / 3600);
  buffer.put(':');
  put_two_digits(buffer, seconds / 60 % 60);
  buffer.put(':');
  put_two_digits(buffer, seconds % 60);
  buffer.put(':');
  put_two_digits(buffer, frames % fps);
  buffer.put('.');
  const std::int64_t fraction = milliframes % 1000;
  if (fraction < 100) buffer.put('0');
  if (fraction < 10) buffer.put('0');
  buffer.put_integer(fraction);
}

void write_arkit_csv(const NamedTrackView& view, std::ostream& out) {
  const Track& track = view.track;
  if (track.fps < 1) throw std::invalid_argument("arkit-csv needs a track frame rate of at least 1 fps");
  if (view.arkit_names.empty()) throw std::invalid_argument("arkit-csv needs the track's ARKit weights");
  const auto columns = live_link_face_columns(view.arkit_names);
  TextBuffer buffer(out);
  buffer.put("Timecode,BlendShapeCount");
  for (std::string_view name : kLiveLinkFaceShapes) {
    buffer.put(',');
    buffer.put(name);
  }
  for (std::string_view name : kLiveLinkFaceRotations) {
    buffer.put(',');
    buffer.put(name);
  }
  buffer.put('\n');

  for (std::size_t f = 0; f < track.frame_count(); ++f) {
    const auto arkit = frame_arkit(view, f);
    put_timecode(buffer, track.t_us[f], track.fps);
    buffer.put(',');
    buffer.put_integer(static_cast<std::int64_t>(kLiveLinkFaceCount));
    for (const std::optional<std::size_t>& index : columns) {
      buffer.put(',');
      buffer.put_float(index ? arkit[*index] : 0.0F, "nan");
    }
    for (std::size_t r = 0; r < kLiveLinkFaceRotations.size(); ++r) buffer.put(",0");
    buffer.put('\n');
    buffer.end_record();
  }
  buffer.flush();
}

/// Throws std::invalid_argument unless the track's times, kinds and values agree.
void check_track_arrays(const Track& track) {
  if (track.kinds.size() != track.frame_count() || track.values.size() != track.frame_count() * track.channel_count) {
    throw std::invalid_argument("track arrays disagree: " + std::to_string(track.frame_count()) + " times, " +
                                std::to_string(track.kinds.size()) + " kinds, " + std::to_string(track.values.size()) +
                                " values");
  }
}

}  // namespace

std::string_view to_string(TrackFormat format) { return name_of(kTrackFormats, format); }

std::optional<TrackFormat> track_format_from_string(std::string_view name) { return format_named(kTrackFormats, name); }

void write_track(const NamedTrackView& view, TrackFormat format, std::ostream& out) {
  const Track& track = view.track;
  if (view.channel_names.size() != track.channel_count) {
    throw std::invalid_argument("track has " + std::to_string(track.channel_count) + " channels but " +
                                std::to_string(view.channel_names.size()) + " channel names");
  }
  check_track_arrays(track);
  if (view.arkit.size() != track.frame_count() * view.arkit_names.size()) {
    throw std::invalid_argument("track has " + std::to_string(track.frame_count()) + " frames of " +
                                std::to_string(view.arkit_names.size()) + " ARKit weights but " +
                                std::to_string(view.arkit.size()) + " weights were given");
  }
  switch (format) {
    case TrackFormat::json:
      write_json(view, out);
      return;
    case TrackFormat::csv:
      write_csv(view, out);
      return;
    case TrackFormat::arkit_csv:
      write_arkit_csv(view, out);
      return;
  }
}

void write_track(const Track& track, const ArticulationModel& model, TrackFormat format, std::ostream& out) {
  if (track.channel_count != model.channel_count()) {
    throw std::invalid_argument("track has " + std::to_string(track.channel_count) + " channels but model '" +
                                model.name() + "' has " + std::to_string(model.channel_count()));
  }
  check_track_arrays(track);  // before retargeting reads every frame
  std::vector<std::string_view> channel_names;
  channel_names.reserve(model.channel_count());
  for (const ChannelSpec& channel : model.channels()) channel_names.emplace_back(channel.name);
  // The csv has no ARKit columns, so it is written without the weights.
  std::vector<float> arkit;
  std::span<const std::string_view> arkit_names;
  if (format != TrackFormat::csv) {
    arkit_names = kArkitNames;
    arkit.resize(track.frame_count() * kArkitNames.size());
    for (std::size_t f = 0; f < track.frame_count(); ++f) {
      model.retarget_to_arkit(track.frame_values(f),
                              std::span<float>(arkit).subspan(f * kArkitNames.size(), kArkitNames.size()));
    }
  }
  write_track(NamedTrackView{.model = model.name(),
                             .channel_names = channel_names,
                             .arkit_names = arkit_names,
                             .track = track,
                             .arkit = arkit},
              format, out);
}

}  // namespace lipsync
