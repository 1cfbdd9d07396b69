// Praat TextGrid reader: three spellings, UTF-8 / UTF-16, tier choice, errors.
#include "format_test_support.hpp"

namespace lipsync {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;
using testing_support::fixture;
using testing_support::Interval;
using testing_support::parse_error;
using testing_support::Timing;

LabeledUtterance parse_grid(std::string_view content, std::string tier = "phones") {
  ParseOptions options;
  options.tier = std::move(tier);
  return parse_utterance(content, InputFormat::textgrid, "speech.TextGrid", options);
}

InputError grid_error(std::string_view content, std::string tier = "phones") {
  ParseOptions options;
  options.tier = std::move(tier);
  return parse_error(content, InputFormat::textgrid, options);
}

// The phones tier of speech_*.TextGrid, without line numbers.
auto speech_phones() {
  return ElementsAre(Timing("", 0, 50000), Timing("S", 50000, 160000), Timing("P", 160000, 230000),
                     Timing("IY1", 230000, 350000), Timing("CH", 350000, 480000), Timing("", 480000, 620000));
}

TEST(TextGrid, ReadsLongFormatWithTheLineOfEachLabel) {
  const LabeledUtterance utterance = parse_grid(fixture("speech_long.TextGrid"));
  EXPECT_EQ(utterance.source, "speech.TextGrid");
  EXPECT_EQ(utterance.phone_set, "");
  EXPECT_THAT(utterance.intervals, ElementsAre(Interval("", 0, 50000, 36), Interval("S", 50000, 160000, 40),
                                               Interval("P", 160000, 230000, 44), Interval("IY1", 230000, 350000, 48),
                                               Interval("CH", 350000, 480000, 52), Interval("", 480000, 620000, 56)));
}

TEST(TextGrid, ShortFormatMatchesLongFormat) {
  const LabeledUtterance utterance = parse_grid(fixture("speech_short.TextGrid"));
  EXPECT_THAT(utterance.intervals, speech_phones());
  EXPECT_EQ(utterance.intervals[1].line, 32);
}

TEST(TextGrid, ChronologicalFormatMatchesLongFormat) {
  const LabeledUtterance utterance = parse_grid(fixture("speech_chronological.TextGrid"));
  EXPECT_THAT(utterance.intervals, speech_phones());
  EXPECT_EQ(utterance.intervals[1].line, 22);
}

TEST(TextGrid, AllSpellingsGiveTheSameWordsTier) {
  for (const char* name : {"speech_long.TextGrid", "speech_short.TextGrid", "speech_chronological.TextGrid"}) {
    SCOPED_TRACE(name);
    EXPECT_THAT(parse_grid(fixture(name), "words").intervals,
                ElementsAre(Timing("", 0, 50000), Timing("speech", 50000, 480000), Timing("", 480000, 620000)));
  }
}

TEST(TextGrid, FreeLayoutWithCommentsIsRead) {
  // The manual's "human-readable" example: data anywhere, '!' comments, no keys.
  const std::string grid =
      "\"ooTextFile\"\n\"TextGrid\"\n0  0.3  ! time domain\n<exists>\n1 tier\n"
      "\"IntervalTier\"  \"phones\"  ! type and name\n0 0.3\n2 intervals coming\n"
      "0 0.1 \"m\"  ! first\n0.1 0.3 \"a\"\n";
  EXPECT_THAT(parse_grid(grid).intervals, ElementsAre(Interval("m", 0, 100000, 9), Interval("a", 100000, 300000, 10)));
}

TEST(TextGrid, DecodesUtf16BigEndianWithByteOrderMark) {
  const LabeledUtterance utf8 = parse_grid(fixture("ipa_utf8.TextGrid"));
  EXPECT_THAT(utf8.intervals, ElementsAre(Interval("", 0, 100000, 36), Interval("ʃ", 100000, 200000, 40),
                                          Interval("iː", 200000, 350000, 44), Interval("p", 350000, 500000, 48),
                                          Interval("", 500000, 600000, 52)));
  const LabeledUtterance utf16 = parse_grid(fixture("ipa_utf16be.TextGrid"));
  EXPECT_THAT(utf16.intervals, ElementsAre(Interval("", 0, 100000, 36), Interval("ʃ", 100000, 200000, 40),
                                           Interval("iː", 200000, 350000, 44), Interval("p", 350000, 500000, 48),
                                           Interval("", 500000, 600000, 52)));
}

TEST(TextGrid, DecodesUtf16LittleEndianWithByteOrderMark) {
  EXPECT_THAT(
      parse_grid(fixture("ipa_utf16le.TextGrid")).intervals,
      ElementsAre(Interval("", 0, 100000, 36), Interval("ʃ", 100000, 200000, 40), Interval("iː", 200000, 350000, 44),
                  Interval("p", 350000, 500000, 48), Interval("", 500000, 600000, 52)));
}

TEST(TextGrid, DoubledQuoteIsOneQuote) {
  for (const char* name : {"ipa_utf8.TextGrid", "ipa_utf16be.TextGrid", "ipa_utf16le.TextGrid"}) {
    SCOPED_TRACE(name);
    EXPECT_THAT(parse_grid(fixture(name), "words").intervals,
                ElementsAre(Timing("", 0, 100000), Timing("say \"ʃiːp\"", 100000, 500000), Timing("", 500000, 600000)));
  }
}

TEST(TextGrid, Utf8ByteOrderMarkAndAnyLineBreakKeepLineNumbers) {
  std::string grid = fixture("speech_short.TextGrid");
  std::string crlf;
  std::string cr;
  for (const char ch : grid) {
    crlf += ch == '\n' ? std::string("\r\n") : std::string(1, ch);
    cr += ch == '\n' ? '\r' : ch;
  }
  for (const std::string& variant : {"\xEF\xBB\xBF" + grid, crlf, cr}) {
    const LabeledUtterance utterance = parse_grid(variant);
    EXPECT_THAT(utterance.intervals, speech_phones());
    EXPECT_EQ(utterance.intervals[1].line, 32);
  }
}

TEST(TextGrid, MissingTierErrorListsTheTiers) {
  const InputError error = grid_error(fixture("speech_long.TextGrid"), "phonemes");
  EXPECT_EQ(error.line(), 0);
  EXPECT_THAT(error.message(), HasSubstr("no tier named \"phonemes\""));
  EXPECT_THAT(error.message(), HasSubstr("\"words\" (interval tier), \"phones\" (interval tier), "
                                         "\"bell\" (point tier)"));
}

TEST(TextGrid, PointTierCannotBeChosen) {
  struct Case {
    const char* name;
    int line;
  };
  for (const Case& c : {Case{"speech_long.TextGrid", 58}, Case{"speech_short.TextGrid", 45},
                        Case{"speech_chronological.TextGrid", 6}}) {
    SCOPED_TRACE(c.name);
    const InputError error = grid_error(fixture(c.name), "bell");
    EXPECT_EQ(error.line(), c.line);
    EXPECT_THAT(error.message(), HasSubstr("\"bell\" is a point tier"));
    EXPECT_THAT(error.message(), HasSubstr("\"words\" (interval tier)"));
  }
}

TEST(TextGrid, DuplicateTierNamesAreAnError) {
  std::string grid = fixture("speech_long.TextGrid");
  grid.replace(grid.find("\"words\""), 7, "\"phones\"");
  const InputError error = grid_error(grid);
  EXPECT_EQ(error.line(), 28);
  EXPECT_THAT(error.message(), HasSubstr("two tiers are named \"phones\" (tiers 1 and 2)"));
}

TEST(TextGrid, ZeroLengthIntervalPassesThrough) {
  const std::string grid =
      "File type = \"ooTextFile\"\nObject class = \"TextGrid\"\n0\n0.2\n<exists>\n1\n"
      "\"IntervalTier\"\n\"phones\"\n0\n0.2\n2\n0\n0.1\n\"a\"\n0.1\n0.1\n\"b\"\n";
  EXPECT_THAT(parse_grid(grid).intervals, ElementsAre(Interval("a", 0, 100000, 14), Interval("b", 100000, 100000, 17)));
}

// The long-format fixture with the first `from` after `after` replaced by `to`
// (`after` is looked for from the phones tier on, or from the start).
std::string edited_long_grid(std::string_view after, std::string_view from, std::string_view to) {
  std::string grid = fixture("speech_long.TextGrid");
  std::size_t anchor = grid.find(after, grid.find("name = \"phones\""));
  if (anchor == std::string::npos) anchor = grid.find(after);
  const std::size_t at = anchor == std::string::npos ? anchor : grid.find(from, anchor);
  if (at == std::string::npos) {
    ADD_FAILURE() << "fixture has no " << from << " after " << after;
    return grid;
  }
  grid.replace(at, from.size(), to);
  return grid;
}

TEST(TextGrid, BadValuesNameLineFieldAndValue) {
  struct Case {
    std::string grid;
    int line;
    std::vector<std::string> parts;
  };
  const Case cases[] = {
      {edited_long_grid("intervals [2]", "xmin = 0.05 ", "xmin = abc "),
       38,
       {"start time (xmin) of interval 2 of 6 on tier \"phones\"", "found \"abc\""}},
      {edited_long_grid("intervals [3]", "xmax = 0.23 ", "xmax = nan "),
       43,
       {"xmax of interval 3 of 6 on tier \"phones\"", "not a finite number", "\"nan\""}},
      {edited_long_grid("intervals [2]", "xmin = 0.05 ", "xmin = -0.05 "),
       38,
       {"xmin of interval 2", "negative", "\"-0.05\""}},
      {edited_long_grid("intervals [6]", "xmax = 0.62 ", "xmax = 620000 "),
       55,
       {"xmax of interval 6", "beyond 24 hours", "\"620000\""}},
      {edited_long_grid("intervals [4]", "text = \"IY1\" ", "text = IY1 "),
       48,
       {"text of interval 4 of 6", "a text in double quotes", "found \"IY1\""}},
      {edited_long_grid("name = \"phones\"", "intervals: size = 6 ", "intervals: size = 2.5 "),
       32,
       {"number of intervals of tier \"phones\"", "not a whole number", "\"2.5\""}},
      {edited_long_grid("name = \"phones\"", "intervals: size = 6 ", "intervals: size = 99999999 "),
       32,
       {"number of intervals of tier \"phones\"", "more than the file can hold"}},
      {edited_long_grid("name = \"phones\"", "intervals: size = 6 ", "intervals: size = 9 "),
       58,
       {"start time (xmin) of interval 7 of 9", "found text \"TextTier\""}},
      {edited_long_grid("item [2]", "\"IntervalTier\"", "\"IntervalTeir\""),
       28,
       {"unknown class of tier 2", "\"IntervalTeir\""}},
      {edited_long_grid("Object", "\"TextGrid\"", "\"Pitch 1\""), 2, {"\"Pitch 1\"", "not a TextGrid"}},
      {edited_long_grid("File type", "\"ooTextFile\"", "\"ooBinaryFile\""),
       1,
       {"binary TextGrid", "Save as text file"}},
      {"just some words\n", 1, {"not a Praat TextGrid text file", "the end of the file"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.parts.front());
    const InputError error = grid_error(c.grid);
    EXPECT_EQ(error.line(), c.line);
    for (const std::string& part : c.parts) EXPECT_THAT(error.message(), HasSubstr(part));
  }
}

TEST(TextGrid, TruncatedShortFormatSaysTheFileEnds) {
  std::string grid = fixture("speech_short.TextGrid");
  grid.resize(grid.find("\"IY1\""));
  const InputError error = grid_error(grid);
  EXPECT_THAT(error.message(), HasSubstr("text of interval 4 of 6 on tier \"phones\""));
  EXPECT_THAT(error.message(), HasSubstr("found the end of the file"));
}

TEST(TextGrid, UnclosedQuoteAtTheEndIsAnError) {
  std::string grid = fixture("speech_long.TextGrid");
  grid.resize(grid.find("IY1\"") + 3);
  const InputError error = grid_error(grid);
  EXPECT_EQ(error.line(), 48);
  EXPECT_THAT(error.message(), HasSubstr("not closed"));
}

TEST(TextGrid, ChronologicalEntryWithBadTierNumberIsAnError) {
  std::string grid = fixture("speech_chronological.TextGrid");
  grid.replace(grid.find("2 0.16 0.23"), 1, "7");
  const InputError error = grid_error(grid);
  EXPECT_EQ(error.line(), 23);
  EXPECT_THAT(error.message(), HasSubstr("tier number from 1 to 3"));
  EXPECT_THAT(error.message(), HasSubstr("number 7"));
}

}  // namespace
}  // namespace lipsync
