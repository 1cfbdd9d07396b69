// libFuzzer target: detect_input_format under every file name extension it
// knows (and none), then parse_utterance in the format it picked.
// Contract: a format or an InputError; then an utterance or an InputError.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.hpp"
#include "lipsync/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lipsync;
  const std::string_view content = fuzz::bytes(data, size);
  for (const std::string_view name : {"input", "input.json", "input.TextGrid", "input.PHN", "input.lab", "input.pho",
                                      "input.psdur", "input.flite", "input.txt"}) {
    InputFormat format;
    try {
      format = detect_input_format(name, content);
    } catch (const InputError&) {
      continue;
    }
    try {
      fuzz::check_utterance(parse_utterance(content, format, name));
    } catch (const InputError&) {
    }
  }
  return 0;
}
