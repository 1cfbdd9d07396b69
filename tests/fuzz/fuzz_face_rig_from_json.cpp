// libFuzzer target: face::FaceRig::from_json against the built-in model.
// Contract: a rig whose muscles name model channels and have fibres whose paths
// have at least two landmarks, or an InputError.
#include <cstddef>
#include <cstdint>

#include "fuzz_support.hpp"
#include "lipsync/error.hpp"
#include "lipsync/face/face_rig.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lipsync;
  const ArticulationModel& model = ArticulationModel::builtin();
  try {
    const face::FaceRig rig = face::FaceRig::from_json(fuzz::bytes(data, size), "fuzz_rig.json", model);
    fuzz::check(rig.channel_count() == model.channel_count(), "the rig has the model's channels");
    fuzz::check(rig.jaw_channel() < model.channel_count(), "the jaw is a model channel");
    for (const face::MuscleSpec& muscle : rig.muscles()) {
      fuzz::check(muscle.channel < model.channel_count(), "a muscle is driven by a model channel");
      fuzz::check(!muscle.fibres.empty(), "a muscle has fibres");
      for (const face::FibreSpec& fibre : muscle.fibres) {
        fuzz::check(fibre.path.size() >= 2, "a fibre path has at least two landmarks");
      }
    }
  } catch (const InputError&) {
  }
  return 0;
}
