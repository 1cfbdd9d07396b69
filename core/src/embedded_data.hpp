// Data files compiled into the library (see core/CMakeLists.txt).
#pragma once

#include <span>
#include <string_view>

namespace lipsync::embedded {

struct EmbeddedFile {
  std::string_view name;  ///< file name without extension
  std::string_view text;  ///< file content
};

/// data/models/default.json
std::string_view default_model_json();
/// data/phonesets/*.json, sorted by file name
std::span<const EmbeddedFile> phone_set_files();

}  // namespace lipsync::embedded
