// lipsync utterance JSON:
//   {"phone_set": "arpabet",                        optional
//    "phonemes": [{"label": "AA1", "start": 0.12, "end": 0.2}, ...]}
// with times in seconds ("start"/"end") or integer microseconds
// ("start_us"/"end_us"); other keys ("text", "audio", "word", ...) are ignored.
//
// Seconds must be exact: 0.171 has to become 171000 µs whatever binary double
// is nearest to it. nlohmann's SAX interface hands us the raw text of each
// floating-point number, so the DOM is built here with every float kept as
// its text (stored in a binary node, which JSON text never produces) and then
// converted by the decimal routine of lipsync/time.hpp.
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "formats/readers.hpp"
#include "formats/text.hpp"
#include "lipsync/error.hpp"
#include "lipsync/time.hpp"

namespace lipsync::formats {
namespace {

using nlohmann::json;

// Builds a json DOM like json::parse, but floats become binary nodes holding
// their decimal text.
class DecimalKeepingBuilder : public nlohmann::json_sax<json> {
 public:
  DecimalKeepingBuilder(std::string_view text, const std::string& source) : text_(text), source_(source) {}

  json& root() { return root_; }

  bool null() override { return add(nullptr); }
  bool boolean(bool value) override { return add(value); }
  bool number_integer(number_integer_t value) override { return add(value); }
  bool number_unsigned(number_unsigned_t value) override { return add(value); }
  bool number_float(number_float_t, const string_t& raw) override {
    json::binary_t bytes;
    for (const char ch : raw) {
      const bool plain = (ch >= '0' && ch <= '9') || ch == '-' || ch == '+' || ch == 'e' || ch == 'E' || ch == '.';
      bytes.push_back(static_cast<std::uint8_t>(plain ? ch : '.'));  // locale decimal point
    }
    return add(json::binary(std::move(bytes)));
  }
  bool string(string_t& value) override { return add(std::move(value)); }
  bool binary(binary_t& value) override { return add(json::binary(std::move(value))); }
  bool start_object(std::size_t) override {
    stack_.push_back(add_node(json::object()));
    return true;
  }
  bool key(string_t& value) override {
    key_ = std::move(value);
    return true;
  }
  bool end_object() override {
    stack_.pop_back();
    return true;
  }
  bool start_array(std::size_t) override {
    stack_.push_back(add_node(json::array()));
    return true;
  }
  bool end_array() override {
    stack_.pop_back();
    return true;
  }
  bool parse_error(std::size_t position, const std::string&, const nlohmann::json::exception& error) override {
    // what(): "[json.exception.parse_error.101] parse error at line 2, column 5: <detail>"
    std::string detail = error.what();
    const std::size_t column = detail.find("column ");
    const std::size_t colon = detail.find(": ", column == std::string::npos ? 0 : column);
    if (colon != std::string::npos) detail.erase(0, colon + 2);
    const std::size_t offset = position > 0 ? std::min(position - 1, text_.size()) : 0;
    int line = 1;
    std::size_t line_start = 0;
    for (std::size_t i = 0; i < offset; ++i) {
      if (text_[i] == '\n') ++line, line_start = i + 1;
    }
    throw InputError(source_, line,
                     "invalid JSON at column " + std::to_string(offset - line_start + 1) + ": " + detail);
  }

 private:
  json* add_node(json value) {
    if (stack_.empty()) {
      root_ = std::move(value);
      return &root_;
    }
    json& parent = *stack_.back();
    if (parent.is_object()) {
      json& slot = parent[key_];
      slot = std::move(value);
      return &slot;
    }
    parent.push_back(std::move(value));
    return &parent.back();
  }

  bool add(json value) {
    add_node(std::move(value));
    return true;
  }

  std::string_view text_;
  const std::string& source_;
  json root_;
  std::vector<json*> stack_;
  std::string key_;
};

// "number 1.5", "string \"0.1\"", "null", "object" for messages.
std::string describe(const json& value) {
  if (value.is_binary()) {
    const json::binary_t& bytes = value.get_binary();
    return "number " + std::string(bytes.begin(), bytes.end());
  }
  if (value.is_string()) return "string " + excerpt(value.get_ref<const std::string&>());
  if (value.is_object() || value.is_array() || value.is_null()) return value.type_name();
  return std::string(value.type_name()) + " " + value.dump();
}

// "start"/"end" in seconds or "start_us"/"end_us" in microseconds.
std::int64_t read_time(const json& phoneme, const std::string& name, const std::string& source, int index) {
  const std::string where = "phoneme " + std::to_string(index) + ": ";
  const std::string name_us = name + "_us";
  const auto seconds = phoneme.find(name);
  const auto micros = phoneme.find(name_us);
  if (seconds != phoneme.end() && micros != phoneme.end()) {
    throw InputError(source, index, where + "has both \"" + name + "\" and \"" + name_us + "\"; give one");
  }
  if (seconds != phoneme.end()) {
    const json& value = *seconds;
    if (value.is_binary()) {
      const json::binary_t& bytes = value.get_binary();
      return seconds_field_to_us(std::string(bytes.begin(), bytes.end()), where + "\"" + name + "\"", source, index);
    }
    if (value.is_number_unsigned() || value.is_number_integer()) {
      return seconds_field_to_us(value.dump(), where + "\"" + name + "\"", source, index);
    }
    throw InputError(source, index, where + "\"" + name + "\" must be a number of seconds, found " + describe(value));
  }
  if (micros != phoneme.end()) {
    const json& value = *micros;
    if (value.is_number_unsigned()) {
      if (value.get<json::number_unsigned_t>() > static_cast<std::uint64_t>(kMaxTimeUs)) {
        throw InputError(
            source, index,
            where + "\"" + name_us + "\" is beyond 24 hours: " + value.dump() + " (microseconds expected)");
      }
      return static_cast<std::int64_t>(value.get<json::number_unsigned_t>());
    }
    if (value.is_number_integer()) {
      throw InputError(source, index, where + "\"" + name_us + "\" is negative: " + value.dump());
    }
    throw InputError(source, index,
                     where + "\"" + name_us + "\" must be a whole number of microseconds, found " + describe(value));
  }
  throw InputError(source, index, where + "missing \"" + name + "\" (seconds) or \"" + name_us + "\" (microseconds)");
}

}  // namespace

LabeledUtterance read_json_utterance(std::string_view text, const std::string& source) {
  DecimalKeepingBuilder builder(text, source);
  json::sax_parse(text, &builder);
  const json& root = builder.root();
  if (!root.is_object()) {
    throw InputError(source, 0, "an utterance must be a JSON object {\"phonemes\": [...]}, found " + describe(root));
  }
  LabeledUtterance utterance{source, "", {}};
  if (const auto phone_set = root.find("phone_set"); phone_set != root.end()) {
    if (!phone_set->is_string()) {
      throw InputError(source, 0, "\"phone_set\" must be a string such as \"arpabet\", found " + describe(*phone_set));
    }
    utterance.phone_set = phone_set->get<std::string>();
  }
  const auto phonemes = root.find("phonemes");
  if (phonemes == root.end()) {
    throw InputError(source, 0,
                     "missing \"phonemes\": expected {\"phonemes\": [{\"label\": \"AA1\", "
                     "\"start\": 0.12, \"end\": 0.2}, ...]}");
  }
  if (!phonemes->is_array()) {
    throw InputError(source, 0, "\"phonemes\" must be an array, found " + describe(*phonemes));
  }
  int index = 0;
  for (const json& phoneme : *phonemes) {
    ++index;
    const std::string where = "phoneme " + std::to_string(index) + ": ";
    if (!phoneme.is_object()) {
      throw InputError(source, index,
                       where + "expected an object {\"label\", \"start\", \"end\"}, found " + describe(phoneme));
    }
    const auto label = phoneme.find("label");
    if (label == phoneme.end()) throw InputError(source, index, where + "missing \"label\"");
    if (!label->is_string()) {
      throw InputError(source, index, where + "\"label\" must be a string, found " + describe(*label));
    }
    const std::int64_t start_us = read_time(phoneme, "start", source, index);
    const std::int64_t end_us = read_time(phoneme, "end", source, index);
    utterance.intervals.push_back({std::string(trim(label->get_ref<const std::string&>())), start_us, end_us, index});
  }
  return utterance;
}

}  // namespace lipsync::formats
