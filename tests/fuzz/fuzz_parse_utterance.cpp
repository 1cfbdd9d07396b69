// libFuzzer target: parse_utterance in one format (LIPSYNC_FUZZ_FORMAT, set by
// tests/fuzz/CMakeLists.txt), then the segment builder over what it returns.
// Contract: an utterance whose times lie within kMaxTimeUs, or an InputError.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.hpp"
#include "lipsync/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lipsync;
  LabeledUtterance utterance;
  try {
    utterance = parse_utterance(fuzz::bytes(data, size), InputFormat::LIPSYNC_FUZZ_FORMAT, "fuzz.input");
  } catch (const InputError&) {
    return 0;
  }
  fuzz::check_utterance(utterance);
  return 0;
}
