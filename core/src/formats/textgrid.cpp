// Praat TextGrid text files: long ("xmin = 0"), short (values only) and
// chronological ("Praat chronological TextGrid text file").
//
// Praat reads its text files as a stream of free-standing data: numbers, texts
// in double quotes (a doubled quote "" stands for one quote) and flags such as
// <exists>; every other word ("xmin", "=", "item", "[1]:") is a comment, and so
// is everything after '!' on a line. Reading the same way makes the long and
// short spellings one grammar:
//   "ooTextFile" "TextGrid" xmin xmax <exists> tier_count
//   per tier: class name xmin xmax count, then per interval xmin xmax text
//             (per point of a "TextTier": time mark)
// The chronological spelling lists the tiers first (class name xmin xmax) and
// then entries "tier_number xmin xmax text" sorted by time; a tier's intervals
// still come in order.
//
// Only the tier named in the options is converted. Its intervals keep their
// labels trimmed ("" is silence) and the line of their text (the label an error names).
#include <limits>
#include <string>
#include <vector>

#include "formats/readers.hpp"
#include "formats/text.hpp"
#include "lipsync/error.hpp"

namespace lipsync::formats {
namespace {

constexpr std::string_view kChronologicalTag = "Praat chronological TextGrid text file";

struct Token {
  enum class Kind { number, text, flag, word, end };  // word: a bad value after "="
  Kind kind = Kind::end;
  std::string value;
  int line = 0;
};

std::string describe(const Token& token) {
  switch (token.kind) {
    case Token::Kind::number:
      return "number " + token.value;
    case Token::Kind::text:
      return "text " + excerpt(token.value);
    case Token::Kind::flag:
      return "flag " + token.value;
    case Token::Kind::word:
      return excerpt(token.value);
    case Token::Kind::end:
      break;
  }
  return "the end of the file";
}

std::string_view describe(Token::Kind kind) {
  switch (kind) {
    case Token::Kind::number:
      return "a number";
    case Token::Kind::text:
      return "a text in double quotes";
    case Token::Kind::flag:
      return "<exists> or <absent>";
    case Token::Kind::word:
    case Token::Kind::end:
      break;
  }
  return "the end of the file";
}

// Splits Praat text into data tokens, dropping comments. The word after a "="
// on the same line is the value of a long-format "key = value" line: when it is
// not data it comes back as a `word` token, so that "xmin = abc" is reported
// where it is instead of silently shifting every later value.
class PraatTokenizer {
 public:
  PraatTokenizer(std::string_view text, const std::string& source) : text_(text), source_(source) {}

  Token next() {
    while (pos_ < text_.size()) {
      const char ch = text_[pos_];
      if (ch == '\n' || ch == '\r') {
        skip_line_break();
        after_equals_ = false;
      } else if (ch == ' ' || ch == '\t' || ch == '\f' || ch == '\v') {
        ++pos_;
      } else if (ch == '!') {
        while (pos_ < text_.size() && text_[pos_] != '\n' && text_[pos_] != '\r') ++pos_;
      } else if (ch == '"') {
        after_equals_ = false;
        return read_text();
      } else {
        const std::size_t start = pos_;
        while (pos_ < text_.size() && !is_space(text_[pos_])) ++pos_;
        const std::string_view word = text_.substr(start, pos_ - start);
        const bool is_value = after_equals_;
        after_equals_ = word == "=";
        if (word == "<exists>" || word == "<absent>") {
          return {Token::Kind::flag, std::string(word), line_};
        }
        if (is_decimal_number(word) || is_non_finite_word(word)) {
          return {Token::Kind::number, std::string(word), line_};
        }
        if (is_value) return {Token::Kind::word, std::string(word), line_};
      }
    }
    const bool ends_with_break = !text_.empty() && (text_.back() == '\n' || text_.back() == '\r');
    return {Token::Kind::end, "", ends_with_break ? line_ - 1 : line_};
  }

 private:
  static bool is_space(char ch) {
    return ch == ' ' || ch == '\t' || ch == '\n' || ch == '\r' || ch == '\f' || ch == '\v';
  }

  void skip_line_break() {
    if (text_[pos_] == '\r' && pos_ + 1 < text_.size() && text_[pos_ + 1] == '\n') ++pos_;
    ++pos_;
    ++line_;
  }

  Token read_text() {
    Token token{Token::Kind::text, "", line_};
    ++pos_;
    while (true) {
      if (pos_ >= text_.size()) {
        throw InputError(source_, token.line, "text in double quotes is not closed before the end of the file");
      }
      const char ch = text_[pos_];
      if (ch == '"') {
        if (pos_ + 1 < text_.size() && text_[pos_ + 1] == '"') {
          token.value.push_back('"');
          pos_ += 2;
          continue;
        }
        ++pos_;
        return token;
      }
      if (ch == '\n' || ch == '\r') {
        const std::size_t start = pos_;
        skip_line_break();
        token.value.append(text_.substr(start, pos_ - start));
        continue;
      }
      token.value.push_back(ch);
      ++pos_;
    }
  }

  std::string_view text_;
  const std::string& source_;
  std::size_t pos_ = 0;
  int line_ = 1;
  bool after_equals_ = false;
};

class TextGridReader {
 public:
  TextGridReader(std::string_view text, const std::string& source, std::string_view tier_name)
      : tokens_(text, source),
        source_(source),
        tier_name_(tier_name),
        max_count_(static_cast<std::int64_t>(text.size())) {}

  LabeledUtterance read() {
    const Token file_type = tokens_.next();
    if (file_type.kind == Token::Kind::text && file_type.value == kChronologicalTag) {
      read_chronological();
    } else if (file_type.kind == Token::Kind::text &&
               (file_type.value == "ooTextFile" || file_type.value == "ooTextFile short")) {
      read_text_file();
    } else if (file_type.kind == Token::Kind::text && file_type.value == "ooBinaryFile") {
      throw InputError(source_, file_type.line,
                       "binary TextGrid files are not supported; in Praat, save the TextGrid "
                       "with \"Save as text file...\"");
    } else {
      throw InputError(source_, file_type.line,
                       "not a Praat TextGrid text file: expected File type = \"ooTextFile\" or "
                       "\"Praat chronological TextGrid text file\" at the start, found " +
                           describe(file_type));
    }
    return finish();
  }

 private:
  struct Tier {
    std::string name;
    bool is_interval = false;
    int line = 0;
  };

  Token expect(Token::Kind kind, const std::string& what) {
    Token token = tokens_.next();
    if (token.kind != kind) {
      throw InputError(source_, token.line,
                       "expected " + what + " (" + std::string(describe(kind)) + "), found " + describe(token));
    }
    return token;
  }

  std::int64_t expect_count(const std::string& what) {
    const Token token = expect(Token::Kind::number, what);
    const std::optional<std::int64_t> count = parse_count(token.value, std::numeric_limits<std::int64_t>::max());
    if (!count) {
      throw InputError(source_, token.line, what + " is not a whole number: " + excerpt(token.value));
    }
    if (*count > max_count_) {
      throw InputError(source_, token.line, what + " is more than the file can hold: " + excerpt(token.value));
    }
    return *count;
  }

  static std::string tier_label(const Tier& tier) { return "tier " + excerpt(tier.name); }

  void read_text_file() {
    const Token object_class = expect(Token::Kind::text, "the object class \"TextGrid\"");
    if (object_class.value != "TextGrid") {
      throw InputError(source_, object_class.line,
                       "this Praat file holds a " + excerpt(object_class.value) + " object, not a TextGrid");
    }
    expect(Token::Kind::number, "the start time (xmin) of the TextGrid");
    expect(Token::Kind::number, "the end time (xmax) of the TextGrid");
    const Token tiers_flag = expect(Token::Kind::flag, "the tiers flag");
    if (tiers_flag.value == "<absent>") return;
    const std::int64_t tier_count = expect_count("the number of tiers");
    for (std::int64_t t = 1; t <= tier_count; ++t) {
      const Tier& tier = read_tier_header("tier " + std::to_string(t));
      const std::string name = tier_label(tier);
      const std::int64_t count = expect_count(
          std::string(tier.is_interval ? "the number of intervals" : "the number of points") + " of " + name);
      for (std::int64_t k = 1; k <= count; ++k) {
        const std::string where = " " + std::to_string(k) + " of " + std::to_string(count) + " on " + name;
        if (tier.is_interval) {
          read_interval(tiers_.size() - 1, "interval" + where);
        } else {
          read_point("point" + where);
        }
      }
    }
  }

  void read_chronological() {
    expect(Token::Kind::number, "the start time of the TextGrid");
    expect(Token::Kind::number, "the end time of the TextGrid");
    const std::int64_t tier_count = expect_count("the number of tiers");
    for (std::int64_t t = 1; t <= tier_count; ++t) read_tier_header("tier " + std::to_string(t));
    std::vector<std::int64_t> seen(tiers_.size(), 0);
    while (true) {
      const Token entry = tokens_.next();
      if (entry.kind == Token::Kind::end) return;
      const std::optional<std::int64_t> tier_number =
          entry.kind == Token::Kind::number ? parse_count(entry.value, tier_count) : std::nullopt;
      if (!tier_number || *tier_number < 1) {
        throw InputError(source_, entry.line,
                         "expected a tier number from 1 to " + std::to_string(tier_count) +
                             " starting an entry, found " + describe(entry));
      }
      const auto index = static_cast<std::size_t>(*tier_number - 1);
      const Tier& tier = tiers_[index];
      const std::string where = " " + std::to_string(++seen[index]) + " on " + tier_label(tier);
      if (tier.is_interval) {
        read_interval(index, "interval" + where);
      } else {
        read_point("point" + where);
      }
    }
  }

  const Tier& read_tier_header(const std::string& which) {
    const Token tier_class = expect(Token::Kind::text, "the class of " + which);
    if (tier_class.value != "IntervalTier" && tier_class.value != "TextTier") {
      throw InputError(source_, tier_class.line,
                       "unknown class of " + which + ": " + excerpt(tier_class.value) +
                           " (expected \"IntervalTier\" or \"TextTier\")");
    }
    const Token name = expect(Token::Kind::text, "the name of " + which);
    expect(Token::Kind::number, "the start time of " + which);
    expect(Token::Kind::number, "the end time of " + which);
    tiers_.push_back({name.value, tier_class.value == "IntervalTier", tier_class.line});
    if (name.value == tier_name_) {
      if (selected_ >= 0) {
        throw InputError(source_, tier_class.line,
                         "two tiers are named " + excerpt(name.value) + " (tiers " + std::to_string(selected_ + 1) +
                             " and " + std::to_string(tiers_.size()) +
                             "); rename one of them so that the choice is clear");
      }
      selected_ = static_cast<int>(tiers_.size()) - 1;
    }
    return tiers_.back();
  }

  void read_interval(std::size_t tier_index, const std::string& which) {
    const Token xmin = expect(Token::Kind::number, "the start time (xmin) of " + which);
    const Token xmax = expect(Token::Kind::number, "the end time (xmax) of " + which);
    const Token text = expect(Token::Kind::text, "the text of " + which);
    if (static_cast<int>(tier_index) != selected_) return;
    const std::int64_t start_us = seconds_field_to_us(xmin.value, "xmin of " + which, source_, xmin.line);
    const std::int64_t end_us = seconds_field_to_us(xmax.value, "xmax of " + which, source_, xmax.line);
    // The line of the label (`text = "..."`), which an error about it names.
    intervals_.push_back({std::string(trim(text.value)), start_us, end_us, text.line});
  }

  void read_point(const std::string& which) {
    expect(Token::Kind::number, "the time of " + which);
    expect(Token::Kind::text, "the mark of " + which);
  }

  LabeledUtterance finish() {
    if (selected_ < 0 || !tiers_[static_cast<std::size_t>(selected_)].is_interval) {
      std::string listing;
      for (const Tier& tier : tiers_) {
        listing += (listing.empty() ? "" : ", ") + excerpt(tier.name) +
                   (tier.is_interval ? " (interval tier)" : " (point tier)");
      }
      if (listing.empty()) listing = "none";
      if (selected_ < 0) {
        throw InputError(source_, 0,
                         "no tier named " + excerpt(tier_name_) + " in this TextGrid; its tiers: " + listing);
      }
      throw InputError(source_, tiers_[static_cast<std::size_t>(selected_)].line,
                       "tier " + excerpt(tier_name_) +
                           " is a point tier (TextTier) and has no intervals; choose an interval "
                           "tier. This TextGrid's tiers: " +
                           listing);
    }
    return {source_, "", std::move(intervals_)};
  }

  PraatTokenizer tokens_;
  const std::string& source_;
  std::string tier_name_;
  std::int64_t max_count_;
  std::vector<Tier> tiers_;
  int selected_ = -1;
  std::vector<LabeledInterval> intervals_;
};

}  // namespace

LabeledUtterance read_textgrid(std::string_view text, const std::string& source, std::string_view tier_name) {
  return TextGridReader(text, source, tier_name).read();
}

}  // namespace lipsync::formats
