// The browser viewer's files (server/web/ and the viewer's face, data/face/viewer_face.json),
// embedded at build time by server/CMakeLists.txt so that lipsyncd serves them with no data
// directory and nothing from a CDN.
#pragma once

#include <span>
#include <string_view>

namespace lipsync::server {

struct WebAsset {
  std::string_view path;          ///< as requested, e.g. "/viewer.js"
  std::string_view content_type;  ///< e.g. "text/javascript; charset=utf-8"
  std::string_view body;
};

std::span<const WebAsset> web_assets();

}  // namespace lipsync::server
