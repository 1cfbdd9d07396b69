// libFuzzer target: ArticulationModel::from_json. Contract: a model whose
// tables have one entry per channel, with targets in the channel's range and a
// silence phoneme, which retargets its rest pose to ARKit weights in [0, 1];
// or an InputError.
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "fuzz_support.hpp"
#include "lipsync/error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lipsync;
  try {
    const ArticulationModel model = ArticulationModel::from_json(fuzz::bytes(data, size), "fuzz_model.json");
    const std::size_t channels = model.channel_count();
    fuzz::check(
        model.silence_phoneme() >= 0 && static_cast<std::size_t>(model.silence_phoneme()) < model.phonemes().size(),
        "the model has a silence phoneme");
    fuzz::check(model.arkit_matrix().size() == kArkitNames.size() * channels, "ARKit matrix is 52 x channels");
    for (const PhonemeSpec& phoneme : model.phonemes()) {
      fuzz::check(phoneme.targets.size() == channels, "one target per channel");
      fuzz::check(phoneme.dominance.size() == channels, "one dominance per channel");
      for (std::size_t i = 0; i < channels; ++i) {
        fuzz::check(phoneme.targets[i] >= model.channels()[i].min && phoneme.targets[i] <= model.channels()[i].max,
                    "targets within the channel's range");
      }
    }
    std::vector<float> rest;
    for (const ChannelSpec& channel : model.channels()) rest.push_back(static_cast<float>(channel.rest));
    std::array<float, 52> arkit{};
    model.retarget_to_arkit(rest, arkit);
    for (const float weight : arkit) fuzz::check(weight >= 0.0f && weight <= 1.0f, "ARKit weights in [0, 1]");
  } catch (const InputError&) {
  }
  return 0;
}
