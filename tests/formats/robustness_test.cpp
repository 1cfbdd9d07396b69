// Property test: mutated fixtures (fixed seed) either parse into intervals whose
// times lie in [0, kMaxTimeUs] or throw InputError; nothing else escapes.
#include <random>

#include "format_test_support.hpp"
#include "lipsync/time.hpp"

namespace lipsync {
namespace {

using testing_support::fixture;

std::string mutated(std::string text, std::mt19937& random) {
  static constexpr std::string_view kBytes = "\"!:;#{}[],.-+e0123456789 \n\r\t\xC3\xFF\xFE";
  const int edits = std::uniform_int_distribution<int>(1, 4)(random);
  for (int i = 0; i < edits; ++i) {
    const std::size_t at = text.empty() ? 0 : random() % text.size();
    const char byte = kBytes[random() % kBytes.size()];
    switch (random() % 3) {
      case 0:
        if (!text.empty()) text[at] = byte;
        break;
      case 1:
        text.insert(text.begin() + static_cast<std::ptrdiff_t>(at), byte);
        break;
      default:
        if (!text.empty()) text.erase(at, 1 + random() % 8);
    }
  }
  return text;
}

TEST(Robustness, MutatedInputsParseOrThrowInputError) {
  const std::pair<const char*, InputFormat> fixtures[] = {
      {"utterance.json", InputFormat::json},
      {"speech_long.TextGrid", InputFormat::textgrid},
      {"speech_short.TextGrid", InputFormat::textgrid},
      {"speech_chronological.TextGrid", InputFormat::textgrid},
      {"ipa_utf16le.TextGrid", InputFormat::textgrid},
      {"speech.PHN", InputFormat::timit},
      {"arctic_style.lab", InputFormat::lab},
      {"speech.pho", InputFormat::pho},
      {"flite_speech_synchronization.psdur", InputFormat::flite},
  };
  std::mt19937 random(20240521);
  int parsed = 0;
  int rejected = 0;
  for (const auto& [name, format] : fixtures) {
    const std::string original = fixture(name);
    for (int round = 0; round < 200; ++round) {
      const std::string content = mutated(original, random);
      for (const InputFormat as : {format, InputFormat::json, InputFormat::textgrid, InputFormat::timit,
                                   InputFormat::lab, InputFormat::pho, InputFormat::flite}) {
        try {
          detect_input_format(name, content);
          const LabeledUtterance utterance = parse_utterance(content, as, name);
          for (const LabeledInterval& interval : utterance.intervals) {
            ASSERT_GE(interval.start_us, 0) << name << " round " << round;
            ASSERT_LE(interval.end_us, kMaxTimeUs) << name << " round " << round;
            ASSERT_GE(interval.line, 1) << name << " round " << round;
          }
          ++parsed;
        } catch (const InputError& error) {
          ASSERT_GE(error.line(), 0);
          ASSERT_FALSE(error.message().empty());
          ++rejected;
        }
      }
    }
  }
  EXPECT_GT(parsed, 0);
  EXPECT_GT(rejected, 0);
}

}  // namespace
}  // namespace lipsync
