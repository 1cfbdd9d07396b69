// lipsync::options, the CLI11 layer both programs parse with: the forms a user
// may write (`--name VALUE`, `--name=VALUE`, `-o VALUE`, `--`, a lone `-`), and
// each mistake coming back as an ArgumentError that names the word and the option.
#include "lipsync/options/command_line.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>

namespace lipsync::options {
namespace {

using ::testing::ElementsAre;

constexpr std::array kShared = {OptionSpec{"server", 0, "ADDR", "lipsyncd address", "127.0.0.1:50051"},
                                OptionSpec{"tls", 0, "", "connect with TLS", ""}};
constexpr auto kOptions = join(kShared, std::to_array<OptionSpec>({
                                            {"fps", 0, "N", "frames per second", "30"},
                                            {"output", 'o', "FILE", "where to write", "-"},
                                            {"model", 0, "NAME=FILE", "an extra model (repeatable)", ""},
                                        }));

ParsedArguments parse(std::vector<std::string> args) { return parse_arguments(std::move(args), kOptions); }

ArgumentError error_of(std::vector<std::string> args) {
  try {
    parse(std::move(args));
  } catch (const ArgumentError& error) {
    return error;
  }
  ADD_FAILURE() << "no ArgumentError";
  return {ArgumentError::Kind::unknown_option, "", "", "", ""};
}

TEST(CommandLine, JoinedTablesKeepTheSharedGroupFirst) {
  ASSERT_EQ(kOptions.size(), 5u);
  EXPECT_EQ(kOptions[0].name, "server");
  EXPECT_EQ(kOptions[1].name, "tls");
  EXPECT_EQ(kOptions[2].name, "fps");
}

TEST(CommandLine, EqualsFormAndSeparateValueGiveTheSameValue) {
  EXPECT_EQ(parse({"--fps=25"}).value("fps"), "25");
  EXPECT_EQ(parse({"--fps", "25"}).value("fps"), "25");
  EXPECT_EQ(parse({"-o", "out.json"}).value("output"), "out.json");
  EXPECT_EQ(parse({"--output=a=b"}).value("output"), "a=b");
}

TEST(CommandLine, AnEmptyEqualsValueIsEmptyAndDoesNotTakeTheNextWord) {
  const ParsedArguments parsed = parse({"--server=", "input.json"});
  EXPECT_EQ(parsed.value("server"), "");
  EXPECT_THAT(parsed.positional(), ElementsAre("input.json"));
}

TEST(CommandLine, FlagsPositionalsAndAbsentOptions) {
  const ParsedArguments parsed = parse({"input.json", "--tls", "-", "-3"});
  EXPECT_TRUE(parsed.flag("tls"));
  EXPECT_FALSE(parsed.flag("server"));
  EXPECT_EQ(parsed.value("server"), std::nullopt);
  EXPECT_THAT(parsed.positional(), ElementsAre("input.json", "-", "-3"));
  EXPECT_FALSE(parsed.help());
  EXPECT_TRUE(parse({"-h"}).help());
  EXPECT_TRUE(parse({"x", "--help"}).help());
}

TEST(CommandLine, DoubleDashEndsTheOptions) {
  const ParsedArguments parsed = parse({"--fps", "24", "--", "--tls", "--frobnicate", "-o"});
  EXPECT_EQ(parsed.value("fps"), "24");
  EXPECT_FALSE(parsed.flag("tls"));
  EXPECT_THAT(parsed.positional(), ElementsAre("--tls", "--frobnicate", "-o"));
}

TEST(CommandLine, ARepeatedOptionKeepsEveryValueInOrderAndTheLastWins) {
  const ParsedArguments parsed = parse({"--model", "a=a.json", "--fps", "1", "--model=b=b.json", "--fps", "2"});
  EXPECT_THAT(parsed.values("model"), ElementsAre("a=a.json", "b=b.json"));
  EXPECT_EQ(parsed.value("fps"), "2");
}

TEST(CommandLine, AnUnknownOptionNamesTheWordAsWritten) {
  for (const std::string word : {"--frobnicate", "--frobnicate=3", "-x"}) {
    const ArgumentError error = error_of({"input.json", word, "value"});
    EXPECT_EQ(error.kind(), ArgumentError::Kind::unknown_option) << word;
    EXPECT_EQ(error.argument(), word);
  }
}

TEST(CommandLine, AMissingValueAtTheEndNamesTheOptionAndItsValueName) {
  const ArgumentError error = error_of({"input.json", "--fps"});
  EXPECT_EQ(error.kind(), ArgumentError::Kind::missing_value);
  EXPECT_EQ(error.option(), "--fps");
  EXPECT_EQ(error.value_name(), "N");
  EXPECT_EQ(error_of({"-o"}).value_name(), "FILE");
}

TEST(CommandLine, AnOptionWhereAValueBelongsIsAMissingValue) {
  for (const auto& args : std::vector<std::vector<std::string>>{{"--server", "--tls"}, {"--server", "-o", "x"}}) {
    const ArgumentError error = error_of(args);
    EXPECT_EQ(error.kind(), ArgumentError::Kind::missing_value) << args[1];
    EXPECT_EQ(error.option(), "--server");
    EXPECT_EQ(error.value_name(), "ADDR");
  }
}

TEST(CommandLine, AFlagGivenAValueNamesTheFlagAndTheValue) {
  const ArgumentError error = error_of({"--fps", "30", "--tls=yes"});
  EXPECT_EQ(error.kind(), ArgumentError::Kind::unexpected_value);
  EXPECT_EQ(error.option(), "--tls");
  EXPECT_EQ(error.value(), "yes");
}

TEST(CommandLine, WholeNumbersAreReadStrictly) {
  EXPECT_EQ(read_whole_number("-42").status, WholeNumber::Status::ok);
  EXPECT_EQ(read_whole_number("-42").value, -42);
  for (const std::string_view text : {"", "30x", " 30", "+3", "2.5", "0x10"}) {
    EXPECT_EQ(read_whole_number(text).status, WholeNumber::Status::not_a_number) << text;
  }
  EXPECT_EQ(read_whole_number("99999999999999999999").status, WholeNumber::Status::beyond_64_bits);
}

}  // namespace
}  // namespace lipsync::options
