#include "quick_try.hpp"

#include <charconv>
#include <limits>
#include <random>

#include "lipsync/error.hpp"
#include "lipsync/formats.hpp"
#include "lipsync/phone_set.hpp"
#include "lipsync/segment.hpp"
#include "lipsync/setting_ranges.hpp"

namespace lipsync::server {
namespace {

constexpr std::string_view kSource = "pasted text";

int hex_digit(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string percent_decode(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '+') {
      out += ' ';
    } else if (text[i] == '%') {
      const int high = i + 2 < text.size() ? hex_digit(text[i + 1]) : -1;
      const int low = i + 2 < text.size() ? hex_digit(text[i + 2]) : -1;
      if (high < 0 || low < 0) {
        throw std::invalid_argument("bad percent escape in '" + std::string(text) + "'");
      }
      out += static_cast<char>(high * 16 + low);
      i += 2;
    } else {
      out += text[i];
    }
  }
  return out;
}

const std::string* parameter(const QueryParameters& query, std::string_view name) {
  const auto found = query.find(name);
  return found == query.end() ? nullptr : &found->second;
}

std::int64_t integer_parameter(const QueryParameters& query, std::string_view name, std::int64_t min, std::int64_t max,
                               std::int64_t fallback) {
  const std::string* text = parameter(query, name);
  if (!text) return fallback;
  std::int64_t value = 0;
  const auto [end, error] = std::from_chars(text->data(), text->data() + text->size(), value);
  if (error != std::errc() || end != text->data() + text->size() || text->empty() || value < min || value > max) {
    throw QuickTryError(std::string(name) + ": expected an integer from " + std::to_string(min) + " to " +
                        std::to_string(max) + ", got '" + *text + "'");
  }
  return value;
}

std::string random_session_name(std::string_view prefix = "try-") {
  static constexpr char kHex[] = "0123456789abcdef";
  std::random_device device;
  std::string name(prefix);
  for (int i = 0; i < 8; ++i) name += kHex[device() % 16];
  return name;
}

v1::VisemeVocabulary viseme_vocabulary(const std::string& name) {
  if (name == "oculus") return v1::VISEME_VOCABULARY_OCULUS;
  if (name == "azure") return v1::VISEME_VOCABULARY_AZURE;
  if (name == "polly") return v1::VISEME_VOCABULARY_POLLY;
  if (name == "rhubarb") return v1::VISEME_VOCABULARY_RHUBARB;
  if (name == "none") return v1::VISEME_VOCABULARY_UNSPECIFIED;
  throw QuickTryError("visemes: unknown vocabulary '" + name + "' (oculus, azure, polly, rhubarb or none)");
}

/// The phone set asked for, else the text's own, else the built-in set that knows every label.
std::string choose_phone_set(const QueryParameters& query, const LabeledUtterance& utterance, const ModelEntry* model) {
  if (const std::string* asked = parameter(query, "phone_set"); asked && !asked->empty() && *asked != "auto") {
    return *asked;
  }
  if (!utterance.phone_set.empty()) return utterance.phone_set;
  if (!model || model->phone_sets.empty()) return "";  // the server names what is wrong
  std::vector<std::string_view> labels;
  for (const LabeledInterval& interval : utterance.intervals) labels.push_back(interval.label);
  return detect_phone_set(model->phone_sets, labels).name();
}

}  // namespace

std::string split_request_target(std::string_view target, QueryParameters& query) {
  const auto question = target.find('?');
  std::string path = percent_decode(target.substr(0, question));
  if (question == std::string_view::npos) return path;
  std::string_view rest = target.substr(question + 1);
  while (!rest.empty()) {
    const auto amp = rest.find('&');
    const std::string_view pair = rest.substr(0, amp);
    rest = amp == std::string_view::npos ? std::string_view{} : rest.substr(amp + 1);
    if (pair.empty()) continue;
    const auto eq = pair.find('=');
    query[percent_decode(pair.substr(0, eq))] =
        eq == std::string_view::npos ? std::string{} : percent_decode(pair.substr(eq + 1));
  }
  return path;
}

namespace {

/// The settings the quick tries and the page's live voice take from the query: session, model,
/// fps, mesh, visemes, lead_ms (`default_lead_ms` when absent).
v1::AnimationSettings quick_try_settings(const QueryParameters& query, std::int64_t now_unix_us,
                                         std::string_view session_prefix = "try-",
                                         std::int64_t default_lead_ms = 1'000) {
  v1::AnimationSettings settings;
  const std::string* session = parameter(query, "session");
  settings.set_session(session && !session->empty() ? *session : random_session_name(session_prefix));
  if (const std::string* model = parameter(query, "model")) settings.set_model(*model);
  settings.set_fps(static_cast<std::uint32_t>(
      integer_parameter(query, "fps", kFpsSetting.min, kFpsSetting.max, kFpsSetting.default_value)));
  const bool mesh = integer_parameter(query, "mesh", 0, 1, 0) == 1;
  settings.mutable_outputs()->mutable_mesh()->set_enabled(mesh);
  const std::string* visemes = parameter(query, "visemes");
  const v1::VisemeVocabulary vocabulary = viseme_vocabulary(visemes ? *visemes : "oculus");
  if (vocabulary != v1::VISEME_VOCABULARY_UNSPECIFIED) {
    settings.mutable_outputs()->mutable_visemes()->set_enabled(true);
    settings.mutable_outputs()->mutable_visemes()->set_vocabulary(vocabulary);
  }
  const std::int64_t lead_ms = integer_parameter(query, "lead_ms", 0, 60'000, default_lead_ms);
  settings.mutable_media_clock()->set_clock("unix");
  settings.mutable_media_clock()->set_utterance_zero_us(now_unix_us + lead_ms * 1000);
  return settings;
}

}  // namespace

QuickTry plan_quick_try(const QueryParameters& query, std::string_view text, const ModelCatalog& catalog,
                        std::int64_t now_unix_us) {
  QuickTry plan;
  v1::AnimationSettings& settings = plan.settings;
  settings = quick_try_settings(query, now_unix_us);

  InputFormat format{};
  if (const std::string* name = parameter(query, "format"); name && !name->empty()) {
    const auto known = input_format_from_string(*name);
    if (!known) {
      throw QuickTryError("format: unknown input format '" + *name + "' (json, textgrid, timit, lab, pho or flite)");
    }
    format = *known;
  } else {
    format = detect_input_format(kSource, text);
  }
  const LabeledUtterance utterance = parse_utterance(text, format, kSource);
  if (utterance.intervals.empty()) throw InputError(std::string(kSource), 0, "no phonemes in the text");
  const ModelEntry* model = catalog.find(settings.model());
  settings.set_phone_set(choose_phone_set(query, utterance, model));
  // Labels and timing checked here, so that errors name the pasted text's lines (the server would
  // name the phoneme's index in the stream); an unknown model or phone set is left to the server.
  if (const PhoneSet* phone_set = model ? model->find_phone_set(settings.phone_set()) : nullptr) {
    build_segments(utterance, *model->model, *phone_set);
  }
  for (const LabeledInterval& interval : utterance.intervals) {
    v1::Phoneme& phoneme = plan.phonemes.emplace_back();
    phoneme.set_label(interval.label);
    phoneme.set_start_us(interval.start_us);
    phoneme.set_end_us(interval.end_us);
  }
  return plan;
}

v1::SpeakRequest plan_quick_speak(const QueryParameters& query, std::string_view text, std::int64_t now_unix_us) {
  v1::SpeakRequest request;
  *request.mutable_settings() = quick_try_settings(query, now_unix_us);
  request.set_text(std::string(text));
  if (const std::string* voice = parameter(query, "voice")) request.set_voice(*voice);
  return request;
}

v1::ListenSettings plan_page_listen(const QueryParameters& query, std::int64_t now_unix_us) {
  v1::ListenSettings settings;
  v1::AnimationSettings& animation = *settings.mutable_animation();
  animation = quick_try_settings(query, now_unix_us, "mic-", 0);
  // The page knows when it heard the first sample; its own clock, on the "unix" scale.
  if (parameter(query, "utterance_zero_us")) {
    animation.mutable_media_clock()->set_utterance_zero_us(
        integer_parameter(query, "utterance_zero_us", 0, std::numeric_limits<std::int64_t>::max(), 0));
  }
  if (!parameter(query, "rate")) {
    throw QuickTryError("rate: required, the sample rate of the 16-bit pieces the page sends (8000 to 48000)");
  }
  settings.set_encoding(v1::AUDIO_ENCODING_PCM_S16LE);
  settings.set_sample_rate_hz(static_cast<std::uint32_t>(integer_parameter(query, "rate", 8'000, 48'000, 0)));
  settings.set_channels(static_cast<std::uint32_t>(integer_parameter(query, "channels", 1, 2, 1)));
  if (parameter(query, "latency_ms")) {
    settings.set_latency_ms(static_cast<std::uint32_t>(integer_parameter(query, "latency_ms", 100, 2'000, 0)));
  }
  if (const std::string* transcript = parameter(query, "transcript"); transcript && !transcript->empty()) {
    settings.set_transcript(*transcript);
  }
  if (const std::string* voice = parameter(query, "voice")) settings.set_voice(*voice);
  return settings;
}

}  // namespace lipsync::server
