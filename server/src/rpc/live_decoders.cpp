// Decoders for Listen's live streams, loaded ahead (rpc/live_decoders.hpp).
#include "rpc/live_decoders.hpp"

#include <algorithm>
#include <exception>
#include <mutex>
#include <utility>
#include <vector>

#include "lipsync/speech/live_recognizer.hpp"

namespace lipsync::server {

struct LiveDecoderPool::Shelf {
  struct Kind {
    speech::LiveRecognitionOptions options;
    speech::PreparedLiveDecoder ready;  // null while it loads, or when a load failed
    bool loading = false;
  };
  std::mutex mutex;
  std::vector<Kind> kinds;  // the kind asked for last at the back
};

LiveDecoderPool::LiveDecoderPool(FaceWorkers& workers) : workers_(workers), shelf_(std::make_shared<Shelf>()) {}

speech::PreparedLiveDecoder LiveDecoderPool::take(const speech::LiveRecognitionOptions& options) {
  speech::PreparedLiveDecoder taken;
  {
    std::lock_guard lock(shelf_->mutex);
    auto& kinds = shelf_->kinds;
    auto kind = std::find_if(kinds.begin(), kinds.end(),
                             [&](const Shelf::Kind& k) { return speech::same_live_decoder(k.options, options); });
    if (kind == kinds.end()) {
      if (kinds.size() == kMaxKinds) kinds.erase(kinds.begin());
      kinds.push_back({options, nullptr, false});
    } else {
      std::rotate(kind, kind + 1, kinds.end());  // now the last asked for
    }
    Shelf::Kind& asked = kinds.back();
    taken = std::move(asked.ready);
    if (asked.loading) return taken;
    asked.loading = true;
  }
  speech::LiveRecognitionOptions load_options = options;
  load_options.transcript = options.transcript ? std::optional<std::string>("") : std::nullopt;
  workers_.post([shelf = shelf_, load_options] {
    speech::PreparedLiveDecoder loaded;
    try {
      loaded = speech::prepare_live_decoder(load_options, "a spare decoder");
    } catch (const std::exception&) {
      // The model cannot be loaded: the stream that asks next loads its own and says why.
    }
    std::lock_guard lock(shelf->mutex);
    for (Shelf::Kind& kind : shelf->kinds) {
      if (!speech::same_live_decoder(kind.options, load_options)) continue;
      kind.loading = false;
      if (!kind.ready) kind.ready = std::move(loaded);
      return;
    }  // the kind was pushed out meanwhile: the decoder goes
  });
  return taken;
}

std::size_t LiveDecoderPool::ready() const {
  std::lock_guard lock(shelf_->mutex);
  return static_cast<std::size_t>(
      std::count_if(shelf_->kinds.begin(), shelf_->kinds.end(), [](const Shelf::Kind& kind) { return !!kind.ready; }));
}

}  // namespace lipsync::server
