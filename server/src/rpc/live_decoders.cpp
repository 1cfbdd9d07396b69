// Decoders for Listen's live streams, loaded ahead (rpc/live_decoders.hpp).
#include "rpc/live_decoders.hpp"

#include <algorithm>
#include <exception>
#include <mutex>
#include <optional>
#include <string>
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

LiveDecoderPool::LiveDecoderPool() : shelf_(std::make_shared<Shelf>()) {}

speech::PreparedLiveDecoder LiveDecoderPool::take(const speech::LiveRecognitionOptions& options) {
  speech::PreparedLiveDecoder taken;
  std::vector<speech::LiveRecognitionOptions> to_load;
  std::optional<speech::LiveRecognitionOptions> companion;
  {
    std::lock_guard lock(shelf_->mutex);
    auto& kinds = shelf_->kinds;
    const auto find = [&](const speech::LiveRecognitionOptions& wanted) {
      return std::find_if(kinds.begin(), kinds.end(),
                          [&](const Shelf::Kind& k) { return speech::same_live_decoder(k.options, wanted); });
    };
    auto kind = find(options);
    if (kind == kinds.end()) {
      // The other kind (with a transcript, or from the audio alone) is loaded too: a server that
      // listens is asked for both (the page's voice with words and without), and the first stream
      // of the second kind then starts on time as well.
      speech::LiveRecognitionOptions other = options;
      other.transcript = options.transcript ? std::nullopt : std::optional<std::string>("");
      if (kinds.size() + 2 <= kMaxKinds && find(other) == kinds.end()) {
        kinds.push_back({other, nullptr, true});
        companion = other;  // loaded after the asked kind's spare
      }
      if (kinds.size() == kMaxKinds) kinds.erase(kinds.begin());
      kinds.push_back({options, nullptr, false});
    } else {
      std::rotate(kind, kind + 1, kinds.end());  // now the last asked for
    }
    Shelf::Kind& asked = kinds.back();
    taken = std::move(asked.ready);
    if (!asked.loading) {
      asked.loading = true;
      to_load.push_back(options);
    }
    if (companion) to_load.push_back(*companion);
  }
  for (const speech::LiveRecognitionOptions& options_to_load : to_load) load(options_to_load);
  return taken;
}

void LiveDecoderPool::load(const speech::LiveRecognitionOptions& options) {
  speech::LiveRecognitionOptions load_options = options;
  load_options.transcript = options.transcript ? std::optional<std::string>("") : std::nullopt;
  loader_.post([shelf = shelf_, load_options] {
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
}

std::size_t LiveDecoderPool::ready() const {
  std::lock_guard lock(shelf_->mutex);
  return static_cast<std::size_t>(
      std::count_if(shelf_->kinds.begin(), shelf_->kinds.end(), [](const Shelf::Kind& kind) { return !!kind.ready; }));
}

}  // namespace lipsync::server
