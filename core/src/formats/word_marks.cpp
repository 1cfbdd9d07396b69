// Word marks of Polly, ElevenLabs and Azure (lipsync/word_marks.hpp).
//
// The file is read whole as JSON first (an ElevenLabs alignment, an Azure array, or a single
// mark); when it is not one JSON value it is read as JSON lines (Polly, Azure events logged one
// a line). Each mark object is told apart by its fields; a word's time is checked on the way in.
#include "lipsync/word_marks.hpp"

#include <cmath>
#include <nlohmann/json.hpp>
#include <optional>

#include "lipsync/error.hpp"
#include "lipsync/time.hpp"

namespace lipsync {
namespace {

using nlohmann::json;

constexpr std::int64_t kTicksPerUs = 10;  // Azure's ticks are 100 ns

/// Where a mark is, for errors: a line of JSON lines, or an item of an array.
struct Place {
  int line = 0;
  std::string item;  // "item 3: " for an array's, "" on a line
};

class MarkReader {
 public:
  explicit MarkReader(const std::string& source) : source_(source) {}

  std::vector<TimedWord> words;

  [[noreturn]] void fail(const Place& place, const std::string& message) const {
    throw InputError(source_, place.line, place.item + message);
  }

  void add(const Place& place, std::string text, std::int64_t start_us, const std::string& field) {
    if (start_us < 0 || start_us > kMaxTimeUs) {
      fail(place, field + " " + std::to_string(start_us) + " us is outside 0 to 24 h");
    }
    if (!words.empty() && start_us < words.back().start_us) {
      fail(place, "word '" + text + "' starts at " + std::to_string(start_us) + " us, before the word before it ('" +
                      words.back().text + "' at " + std::to_string(words.back().start_us) +
                      " us): marks come in the order the words are spoken");
    }
    words.push_back({std::move(text), start_us});
  }

  std::int64_t integer(const Place& place, const json& object, const char* field, const char* what) const {
    const auto it = object.find(field);
    if (it == object.end()) fail(place, std::string(what) + " without \"" + field + "\"");
    if (!it->is_number_integer()) {
      fail(place, std::string("\"") + field + "\" of " + what + " is " + it->dump() + ", not a whole number");
    }
    return it->get<std::int64_t>();
  }

  std::string string(const Place& place, const json& object, const char* field, const char* what) const {
    const auto it = object.find(field);
    if (it == object.end()) fail(place, std::string(what) + " without \"" + field + "\"");
    if (!it->is_string()) fail(place, std::string("\"") + field + "\" of " + what + " is " + it->dump() + ", not text");
    return it->get<std::string>();
  }

  /// One object of an array or a line: a Polly mark, an Azure event or metadata message.
  void mark(const Place& place, const json& object) {
    if (!object.is_object()) fail(place, "a mark is " + object.dump() + ", not a JSON object");
    if (object.contains("type") && object.contains("time")) {  // Polly
      if (object["type"] != "word") return;
      const std::int64_t ms = integer(place, object, "time", "a Polly word mark");
      if (std::abs(ms) > kMaxTimeUs / 1000) fail(place, "\"time\" " + std::to_string(ms) + " ms is outside 0 to 24 h");
      add(place, string(place, object, "value", "a Polly word mark"), ms * 1000, "\"time\"");
    } else if (object.contains("AudioOffset")) {  // Azure SDK WordBoundary event
      const auto type = object.find("BoundaryType");
      if (type != object.end() && type->is_string() && *type != "Word" && *type != "WordBoundary") return;
      const std::int64_t ticks = integer(place, object, "AudioOffset", "an Azure word boundary");
      add(place, string(place, object, "Text", "an Azure word boundary"), ticks / kTicksPerUs, "\"AudioOffset\"");
    } else if (object.contains("Metadata")) {  // Azure audio.metadata message
      const json& metadata = object["Metadata"];
      if (!metadata.is_array()) fail(place, "\"Metadata\" is " + metadata.dump() + ", not an array");
      for (const json& entry : metadata) {
        if (!entry.is_object() || entry.value("Type", "") != "WordBoundary") continue;
        const auto data = entry.find("Data");
        if (data == entry.end() || !data->is_object()) fail(place, "a WordBoundary entry without \"Data\"");
        const auto text = data->find("text");
        if (text == data->end() || !text->is_object()) fail(place, "a WordBoundary's \"Data\" without \"text\"");
        const auto boundary = text->find("BoundaryType");
        if (boundary != text->end() && boundary->is_string() && *boundary != "WordBoundary") continue;
        const std::int64_t ticks = integer(place, *data, "Offset", "a WordBoundary's Data");
        add(place, string(place, *text, "Text", "a WordBoundary's Data.text"), ticks / kTicksPerUs, "\"Offset\"");
      }
    } else {
      fail(place,
           "a mark with none of the fields lipsync reads (Polly's \"type\" and \"time\", Azure's \"AudioOffset\" or "
           "\"Metadata\", ElevenLabs' \"characters\"): " +
               object.dump().substr(0, 80));
    }
  }

  /// An ElevenLabs alignment: characters and their start times; words are runs without spaces.
  void alignment(const json& object) {
    const Place place;
    const auto characters = object.find("characters");
    const auto starts = object.find("character_start_times_seconds");
    if (characters == object.end() || !characters->is_array()) fail(place, "an alignment without \"characters\"");
    if (starts == object.end() || !starts->is_array()) {
      fail(place, "an alignment without \"character_start_times_seconds\"");
    }
    if (characters->size() != starts->size()) {
      fail(place, std::to_string(characters->size()) + " characters but " + std::to_string(starts->size()) +
                      " character_start_times_seconds");
    }
    std::string word;
    std::int64_t word_start_us = 0;
    for (std::size_t i = 0; i < characters->size(); ++i) {
      const json& character = (*characters)[i];
      const json& start = (*starts)[i];
      const Place at{0, "character " + std::to_string(i + 1) + ": "};
      if (!character.is_string()) fail(at, "\"characters\" holds " + character.dump() + ", not a character");
      if (!start.is_number()) fail(at, "its start time is " + start.dump() + ", not a number of seconds");
      const std::optional<std::int64_t> start_us = seconds_to_us(start.get<double>());
      if (!start_us) fail(at, "its start time " + start.dump() + " s is outside 0 to 24 h");
      const std::string& text = character.get_ref<const std::string&>();
      const bool space = text.empty() || text.find_first_not_of(" \t\r\n") == std::string::npos;
      if (space) {
        if (!word.empty()) add(at, std::move(word), word_start_us, "its start time");
        word.clear();
        continue;
      }
      if (word.empty()) word_start_us = *start_us;
      word += text;
    }
    if (!word.empty()) add(Place{0, "the last word: "}, std::move(word), word_start_us, "its start time");
  }

 private:
  const std::string& source_;
};

}  // namespace

std::vector<TimedWord> read_word_marks(std::string_view text, const std::string& source) {
  MarkReader reader(source);
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) {
    throw InputError(source, 0, "no word marks: the file is empty");
  }
  const json whole = json::parse(text, nullptr, false);
  if (!whole.is_discarded()) {
    if (whole.is_object() && whole.contains("characters")) {
      reader.alignment(whole);
    } else if (whole.is_object() && (whole.contains("alignment") || whole.contains("normalized_alignment"))) {
      const json& alignment = whole.contains("alignment") ? whole["alignment"] : whole["normalized_alignment"];
      if (!alignment.is_object()) throw InputError(source, 0, "\"alignment\" is not an object");
      reader.alignment(alignment);
    } else if (whole.is_array()) {
      for (std::size_t i = 0; i < whole.size(); ++i)
        reader.mark(Place{0, "item " + std::to_string(i + 1) + ": "}, whole[i]);
    } else {
      reader.mark(Place{1, ""}, whole);
    }
  } else {
    int line_number = 0;
    std::size_t begin = 0;
    while (begin <= text.size()) {
      const std::size_t end = std::min(text.find('\n', begin), text.size());
      const std::string_view line = text.substr(begin, end - begin);
      ++line_number;
      begin = end + 1;
      if (line.find_first_not_of(" \t\r") == std::string_view::npos) continue;
      const json object = json::parse(line, nullptr, false);
      if (object.is_discarded()) {
        throw InputError(source, line_number,
                         "not JSON (word marks are Polly's or Azure's JSON lines, an ElevenLabs alignment or a JSON "
                         "array): " +
                             std::string(line.substr(0, 60)));
      }
      reader.mark(Place{line_number, ""}, object);
    }
  }
  if (reader.words.empty()) throw InputError(source, 0, "no word marks in the file (no word with a time)");
  return std::move(reader.words);
}

}  // namespace lipsync
