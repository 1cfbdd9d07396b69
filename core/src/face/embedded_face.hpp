// The face data files compiled into the library (see core/CMakeLists.txt).
#pragma once

#include <string_view>

namespace lipsync::embedded {

/// data/face/canonical_face.json
std::string_view canonical_face_json();
/// data/face/rig.json
std::string_view face_rig_json();

}  // namespace lipsync::embedded
