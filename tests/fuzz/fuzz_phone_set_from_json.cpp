// libFuzzer target: PhoneSet::from_json against the built-in model.
// Contract: a phone set whose lookups give model phoneme indices (silence for
// the empty label), or an InputError.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.hpp"
#include "lipsync/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lipsync;
  const ArticulationModel& model = ArticulationModel::builtin();
  const std::string_view content = fuzz::bytes(data, size);
  try {
    const PhoneSet phone_set = PhoneSet::from_json(content, "fuzz_phone_set.json", model);
    fuzz::check(phone_set.lookup("") == model.silence_phoneme(), "the empty label is silence");
    for (const std::string_view label :
         {std::string_view("aa"), std::string_view("AA1"), std::string_view("p"), content.substr(0, 8)}) {
      if (const auto index = phone_set.lookup(label)) {
        fuzz::check(*index >= 0 && static_cast<std::size_t>(*index) < model.phonemes().size(),
                    "a lookup names a model phoneme");
      }
    }
  } catch (const InputError&) {
  }
  return 0;
}
