// Loading and validating an articulation model (schema: docs/model.md).
//
// from_json reads the sections in the schema's order, one helper each: the header (format,
// version, name; read_header), the channels (read_channels), the dominance defaults
// (read_dominance), the phonemes with their targets and dominance and each release's closure
// (read_phonemes, read_phoneme), the silence phoneme (silence_index) and the ARKit matrix
// (read_arkit). ObjectReader remembers the keys it read, so a misspelt key is an error.
//
// Validation happens here, once: every later lookup is by index and trusts the
// model. Each error names the source, the phoneme (or channel, or blendshape)
// and the field, with the offending value.
#include "lipsync/model.hpp"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>

#include "embedded_data.hpp"
#include "lipsync/error.hpp"

namespace lipsync {

const std::array<std::string_view, 52> kArkitNames = {
    "eyeBlinkLeft",      "eyeLookDownLeft",    "eyeLookInLeft",
    "eyeLookOutLeft",    "eyeLookUpLeft",      "eyeSquintLeft",
    "eyeWideLeft",       "eyeBlinkRight",      "eyeLookDownRight",
    "eyeLookInRight",    "eyeLookOutRight",    "eyeLookUpRight",
    "eyeSquintRight",    "eyeWideRight",       "jawForward",
    "jawLeft",           "jawRight",           "jawOpen",
    "mouthClose",        "mouthFunnel",        "mouthPucker",
    "mouthLeft",         "mouthRight",         "mouthSmileLeft",
    "mouthSmileRight",   "mouthFrownLeft",     "mouthFrownRight",
    "mouthDimpleLeft",   "mouthDimpleRight",   "mouthStretchLeft",
    "mouthStretchRight", "mouthRollLower",     "mouthRollUpper",
    "mouthShrugLower",   "mouthShrugUpper",    "mouthPressLeft",
    "mouthPressRight",   "mouthLowerDownLeft", "mouthLowerDownRight",
    "mouthUpperUpLeft",  "mouthUpperUpRight",  "browDownLeft",
    "browDownRight",     "browInnerUp",        "browOuterUpLeft",
    "browOuterUpRight",  "cheekPuff",          "cheekSquintLeft",
    "cheekSquintRight",  "noseSneerLeft",      "noseSneerRight",
    "tongueOut",
};

namespace {
constexpr std::size_t kArkitJawOpen = 17;
constexpr std::size_t kArkitMouthClose = 18;
}  // namespace

std::string_view to_string(PhonemeClass phoneme_class) {
  switch (phoneme_class) {
    case PhonemeClass::vowel:
      return "vowel";
    case PhonemeClass::consonant:
      return "consonant";
    case PhonemeClass::closure:
      return "closure";
    case PhonemeClass::release:
      return "release";
    case PhonemeClass::silence:
      return "silence";
  }
  return "?";
}

std::optional<PhonemeClass> phoneme_class_from_string(std::string_view name) {
  for (auto cls : {PhonemeClass::vowel, PhonemeClass::consonant, PhonemeClass::closure, PhonemeClass::release,
                   PhonemeClass::silence}) {
    if (to_string(cls) == name) return cls;
  }
  return std::nullopt;
}

namespace {

using nlohmann::json;

constexpr std::string_view kFormatTag = "lipsync-articulation-model";
constexpr double kMaxPeakOffsetMs = 500.0;

/// Reads fields of one JSON object, remembering which were used, so that a
/// misspelt key is reported instead of silently ignored.
class ObjectReader {
 public:
  ObjectReader(const json& object, std::string where, const std::string& source)
      : object_(object), where_(std::move(where)), source_(source) {
    if (!object_.is_object()) fail("must be a JSON object");
  }

  [[noreturn]] void fail(const std::string& message) const { throw InputError(source_, 0, where_ + ": " + message); }
  [[noreturn]] void fail_field(std::string_view key, const std::string& message) const {
    throw InputError(source_, 0, where_ + ", field '" + std::string(key) + "': " + message);
  }

  const json* optional(std::string_view key) {
    used_.insert(std::string(key));
    auto it = object_.find(std::string(key));
    return it == object_.end() ? nullptr : &*it;
  }
  const json& required(std::string_view key) {
    const json* value = optional(key);
    if (value == nullptr) fail_field(key, "is missing");
    return *value;
  }
  double number(std::string_view key, const json& value) const {
    if (!value.is_number()) fail_field(key, "must be a number, got " + value.dump());
    const double number = value.get<double>();
    if (!std::isfinite(number)) fail_field(key, "must be finite");
    return number;
  }
  double required_number(std::string_view key) { return number(key, required(key)); }
  std::string required_string(std::string_view key) {
    const json& value = required(key);
    if (!value.is_string()) fail_field(key, "must be a string, got " + value.dump());
    return value.get<std::string>();
  }
  std::string optional_string(std::string_view key) {
    const json* value = optional(key);
    if (value == nullptr) return {};
    if (!value->is_string()) fail_field(key, "must be a string, got " + value->dump());
    return value->get<std::string>();
  }
  /// Fails on any key that was not read and is not documentation.
  void reject_unknown_keys() const {
    for (const auto& [key, value] : object_.items()) {
      if (used_.count(key) == 0 && key != "features" && key != "note" && key != "description") {
        fail("unknown field '" + key + "'");
      }
    }
  }
  const std::string& where() const { return where_; }

 private:
  const json& object_;
  std::string where_;
  const std::string& source_;
  std::set<std::string> used_;
};

/// Applies the dominance keys present in `reader`'s object on top of `params`.
DominanceParams read_dominance(ObjectReader& reader, DominanceParams params) {
  if (const json* v = reader.optional("alpha")) params.alpha = reader.number("alpha", *v);
  if (const json* v = reader.optional("theta_minus_per_s")) {
    params.theta_minus_per_s = reader.number("theta_minus_per_s", *v);
  }
  if (const json* v = reader.optional("theta_plus_per_s")) {
    params.theta_plus_per_s = reader.number("theta_plus_per_s", *v);
  }
  if (const json* v = reader.optional("c")) params.c = reader.number("c", *v);
  if (const json* v = reader.optional("t_off_ms")) params.t_off_s = reader.number("t_off_ms", *v) * 1e-3;
  reader.reject_unknown_keys();
  if (!(params.alpha > 0)) reader.fail_field("alpha", "must be > 0, got " + std::to_string(params.alpha));
  if (!(params.theta_minus_per_s > 0)) {
    reader.fail_field("theta_minus_per_s", "must be > 0, got " + std::to_string(params.theta_minus_per_s));
  }
  if (!(params.theta_plus_per_s > 0)) {
    reader.fail_field("theta_plus_per_s", "must be > 0, got " + std::to_string(params.theta_plus_per_s));
  }
  if (!(params.c >= 1.0 && params.c <= 4.0)) {
    reader.fail_field("c", "must be in [1, 4], got " + std::to_string(params.c));
  }
  if (!(std::fabs(params.t_off_s) * 1e3 <= kMaxPeakOffsetMs)) {
    reader.fail_field("t_off_ms", "must be within ±500 ms, got " + std::to_string(params.t_off_s * 1e3));
  }
  return params;
}

json parse_model_json(std::string_view json_text, const std::string& source) {
  try {
    return json::parse(json_text.begin(), json_text.end());
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number that overflows
    throw InputError(source, 0, std::string("not valid JSON: ") + e.what());
  }
}

/// Checks the format tag and version; returns the model's name.
std::string read_header(ObjectReader& top) {
  if (top.required_string("format") != kFormatTag) {
    top.fail_field("format", "must be \"" + std::string(kFormatTag) + "\"");
  }
  if (const double version = top.required_number("version"); version != 1) {
    top.fail_field("version", "unsupported version " + std::to_string(version) + " (this build reads 1)");
  }
  return top.required_string("name");
}

/// "channels": a non-empty array of uniquely named channels, each with min < max and rest within.
std::vector<ChannelSpec> read_channels(ObjectReader& top, const std::string& source) {
  std::vector<ChannelSpec> out;
  const json& channels = top.required("channels");
  if (!channels.is_array() || channels.empty()) top.fail_field("channels", "must be a non-empty array");
  for (std::size_t i = 0; i < channels.size(); ++i) {
    ObjectReader reader(channels[i], "channel " + std::to_string(i + 1), source);
    ChannelSpec channel;
    channel.name = reader.required_string("name");
    ObjectReader named(channels[i], "channel '" + channel.name + "'", source);
    named.optional("name");
    channel.kind = named.required_string("kind");
    if (channel.kind != "muscle" && channel.kind != "jaw" && channel.kind != "tongue") {
      named.fail_field("kind", "must be muscle, jaw or tongue, got '" + channel.kind + "'");
    }
    channel.min = named.required_number("min");
    channel.max = named.required_number("max");
    channel.rest = named.required_number("rest");
    channel.description = named.optional_string("description");
    named.reject_unknown_keys();
    if (!(channel.min < channel.max)) named.fail("min must be below max");
    if (channel.rest < channel.min || channel.rest > channel.max) {
      named.fail_field("rest", "must lie within [min, max]");
    }
    for (const auto& other : out) {
      if (other.name == channel.name) named.fail("duplicate channel name");
    }
    out.push_back(std::move(channel));
  }
  return out;
}

/// The index of the channel `name`; an unknown name fails in `reader`'s object.
std::size_t channel_index(const std::vector<ChannelSpec>& channels, const ObjectReader& reader,
                          const std::string& name) {
  for (std::size_t i = 0; i < channels.size(); ++i) {
    if (channels[i].name == name) return i;
  }
  reader.fail("unknown channel '" + name + "'");
}

/// A phoneme as read, with the closure it names (a release's, else empty).
struct PhonemeEntry {
  PhonemeSpec spec;
  std::string closure;
};

/// One phoneme of "phonemes": its class, its targets (the channels' rest values where absent),
/// its dominance (the defaults, then the phoneme's, then per channel) and a release's closure.
PhonemeEntry read_phoneme(const std::string& name, const json& body, const std::vector<ChannelSpec>& channels,
                          const DominanceParams& defaults, const std::string& source) {
  ObjectReader reader(body, "phoneme '" + name + "'", source);
  PhonemeSpec spec;
  spec.name = name;
  const std::string class_name = reader.required_string("class");
  const auto cls = phoneme_class_from_string(class_name);
  if (!cls) {
    reader.fail_field("class", "must be vowel, consonant, closure, release or silence, got '" + class_name + "'");
  }
  spec.phoneme_class = *cls;

  spec.targets.resize(channels.size());
  for (std::size_t c = 0; c < channels.size(); ++c) spec.targets[c] = channels[c].rest;
  if (const json* targets = reader.optional("targets")) {
    ObjectReader target_reader(*targets, reader.where() + " targets", source);
    for (const auto& [channel, value] : targets->items()) {
      const std::size_t c = channel_index(channels, target_reader, channel);
      target_reader.optional(channel);
      const double target = target_reader.number(channel, value);
      const ChannelSpec& spec_channel = channels[c];
      if (target < spec_channel.min || target > spec_channel.max) {
        target_reader.fail_field(channel, "target " + value.dump() + " is outside the channel range [" +
                                              std::to_string(spec_channel.min) + ", " +
                                              std::to_string(spec_channel.max) + "]");
      }
      spec.targets[c] = target;
    }
  }

  DominanceParams phoneme_defaults = defaults;
  if (const json* dominance = reader.optional("dominance")) {
    ObjectReader dominance_reader(*dominance, reader.where() + " dominance", source);
    phoneme_defaults = read_dominance(dominance_reader, defaults);
  }
  spec.dominance.assign(channels.size(), phoneme_defaults);
  if (const json* per_channel = reader.optional("channel_dominance")) {
    ObjectReader list_reader(*per_channel, reader.where() + " channel_dominance", source);
    for (const auto& [channel, params] : per_channel->items()) {
      const std::size_t c = channel_index(channels, list_reader, channel);
      ObjectReader channel_reader(params, reader.where() + " channel_dominance '" + channel + "'", source);
      spec.dominance[c] = read_dominance(channel_reader, phoneme_defaults);
    }
  }

  std::string closure = reader.optional_string("closure");
  if (spec.phoneme_class == PhonemeClass::release) {
    if (closure.empty()) reader.fail_field("closure", "is required for a release phoneme");
  } else if (!closure.empty()) {
    reader.fail_field("closure", "is only allowed for release phonemes");
  }
  reader.reject_unknown_keys();

  std::size_t strongest = 0;
  for (std::size_t c = 1; c < spec.dominance.size(); ++c) {
    if (spec.dominance[c].alpha > spec.dominance[strongest].alpha) strongest = c;
  }
  spec.keyframe_t_off_s = spec.dominance[strongest].t_off_s;
  return {std::move(spec), std::move(closure)};
}

std::optional<int> find_phoneme(const std::vector<PhonemeSpec>& phonemes, std::string_view name) {
  for (std::size_t i = 0; i < phonemes.size(); ++i) {
    if (phonemes[i].name == name) return static_cast<int>(i);
  }
  return std::nullopt;
}

/// "phonemes": a non-empty object of phonemes, each release linked to its closure phoneme.
std::vector<PhonemeSpec> read_phonemes(ObjectReader& top, const std::vector<ChannelSpec>& channels,
                                       const DominanceParams& defaults, const std::string& source) {
  std::vector<PhonemeSpec> out;
  const json& phonemes = top.required("phonemes");
  if (!phonemes.is_object() || phonemes.empty()) top.fail_field("phonemes", "must be a non-empty object");
  std::vector<std::pair<std::size_t, std::string>> closure_names;  // release index, closure name
  for (const auto& [name, body] : phonemes.items()) {
    PhonemeEntry entry = read_phoneme(name, body, channels, defaults, source);
    if (entry.spec.phoneme_class == PhonemeClass::release) closure_names.emplace_back(out.size(), entry.closure);
    out.push_back(std::move(entry.spec));
  }
  for (const auto& [release, closure] : closure_names) {
    const auto closure_index = find_phoneme(out, closure);
    const std::string& release_name = out[release].name;
    if (!closure_index) {
      throw InputError(source, 0, "phoneme '" + release_name + "', field 'closure': unknown phoneme '" + closure + "'");
    }
    if (out[static_cast<std::size_t>(*closure_index)].phoneme_class != PhonemeClass::closure) {
      throw InputError(source, 0,
                       "phoneme '" + release_name + "', field 'closure': '" + closure + "' is not of class closure");
    }
    out[release].closure_phoneme = *closure_index;
  }
  return out;
}

/// The index of the phoneme "sil", which must be of class silence.
int silence_index(const std::vector<PhonemeSpec>& phonemes, const std::string& source) {
  const auto silence = find_phoneme(phonemes, "sil");
  if (!silence || phonemes[static_cast<std::size_t>(*silence)].phoneme_class != PhonemeClass::silence) {
    throw InputError(source, 0, "phonemes: the model needs a phoneme 'sil' of class silence");
  }
  return *silence;
}

/// "arkit" (optional): per ARKit blendshape, the weights of the channels; the row-major
/// 52 × channel count matrix, zero where not given.
std::vector<double> read_arkit(ObjectReader& top, const std::vector<ChannelSpec>& channels, const std::string& source) {
  std::vector<double> matrix(kArkitNames.size() * channels.size(), 0.0);
  if (const json* arkit = top.optional("arkit")) {
    ObjectReader arkit_reader(*arkit, "arkit", source);
    for (const auto& [shape, row] : arkit->items()) {
      const auto it = std::find(kArkitNames.begin(), kArkitNames.end(), shape);
      if (it == kArkitNames.end()) {
        arkit_reader.fail("unknown ARKit blendshape '" + shape + "' (names are Apple's, e.g. jawOpen)");
      }
      const auto shape_index = static_cast<std::size_t>(it - kArkitNames.begin());
      arkit_reader.optional(shape);
      ObjectReader row_reader(row, "arkit '" + shape + "'", source);
      const json& weights = row_reader.required("weights");
      row_reader.reject_unknown_keys();
      ObjectReader weight_reader(weights, "arkit '" + shape + "' weights", source);
      for (const auto& [channel, weight] : weights.items()) {
        const std::size_t c = channel_index(channels, weight_reader, channel);
        weight_reader.optional(channel);
        matrix[shape_index * channels.size() + c] = weight_reader.number(channel, weight);
      }
    }
    arkit_reader.reject_unknown_keys();
  }
  return matrix;
}

}  // namespace

ArticulationModel ArticulationModel::from_json(std::string_view json_text, std::string_view source_name) {
  const std::string source(source_name);
  const json root = parse_model_json(json_text, source);
  ArticulationModel model;
  ObjectReader top(root, "model", source);
  model.name_ = read_header(top);
  model.channels_ = read_channels(top, source);
  DominanceParams defaults;
  {
    ObjectReader reader(top.required("dominance_defaults"), "dominance_defaults", source);
    defaults = read_dominance(reader, defaults);
  }
  model.phonemes_ = read_phonemes(top, model.channels_, defaults, source);
  model.silence_phoneme_ = silence_index(model.phonemes_, source);
  model.arkit_matrix_ = read_arkit(top, model.channels_, source);
  top.reject_unknown_keys();
  return model;
}

const ArticulationModel& ArticulationModel::builtin() {
  static const ArticulationModel kModel = from_json(embedded::default_model_json(), "built-in kModel");
  return kModel;
}

std::string_view ArticulationModel::builtin_json() { return embedded::default_model_json(); }

std::optional<int> ArticulationModel::find_phoneme(std::string_view name) const {
  for (std::size_t i = 0; i < phonemes_.size(); ++i) {
    if (phonemes_[i].name == name) return static_cast<int>(i);
  }
  return std::nullopt;
}

void ArticulationModel::retarget_to_arkit(std::span<const float> channel_values, std::span<float> arkit_out) const {
  const std::size_t channels = channels_.size();
  for (std::size_t shape = 0; shape < kArkitNames.size(); ++shape) {
    const double* row = arkit_matrix_.data() + shape * channels;
    double sum = 0.0;
    for (std::size_t c = 0; c < channels; ++c) sum += row[c] * channel_values[c];
    arkit_out[shape] = static_cast<float>(std::clamp(sum, 0.0, 1.0));
  }
  // ARKit's mouthClose closes the lips *against the jaw's opening*: beyond jawOpen it would push
  // them through each other, so it is capped there (docs/output-formats.md, "Closures in ARKit").
  arkit_out[kArkitMouthClose] = std::min(arkit_out[kArkitMouthClose], arkit_out[kArkitJawOpen]);
}

}  // namespace lipsync
