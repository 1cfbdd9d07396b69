// A quick try from the browser viewer: phoneme text pasted into the page (any format the CLI
// reads: lipsync JSON, TextGrid, TIMIT .PHN, Festival .lab, MBROLA .pho, flite -psdur) and the
// query parameters of `POST /sessions`, turned into the settings and phonemes of one Animate call.
//
// The text is parsed by the core's readers under the source name "pasted text", so a bad line is
// reported as the CLI reports it ("pasted text:3: ..."). The phone set is the one asked for, else
// the one the text declares, else the built-in set that knows every label (as the CLI's `auto`).
// The session gets a media-clock anchor on the "unix" clock, `lead_ms` after the request, so a
// page that follows it can start the face and its audio together.
#pragma once

#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "catalog.hpp"
#include "lipsync/v1/lipsync.pb.h"

namespace lipsync::server {

/// Decoded query parameters of a request target, by name (the last one wins).
using QueryParameters = std::map<std::string, std::string, std::less<>>;

/// Splits "/path?a=1&b=x%20y" into the path and its decoded parameters ('+' is a space).
/// Throws std::invalid_argument for a malformed percent escape.
std::string split_request_target(std::string_view target, QueryParameters& query);

/// A parameter of `POST /sessions` that is not valid; the message names it and its value.
class QuickTryError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

struct QuickTry {
  v1::AnimationSettings settings;
  std::vector<v1::Phoneme> phonemes;
};

/// Parameters: session (default "try-" and 8 random hex digits), format (default: detected),
/// phone_set, model, fps, mesh (1: the server simulates the face), visemes (a vocabulary name),
/// lead_ms (0 to 60000, default 1000). Throws QuickTryError for a bad parameter and
/// lipsync::InputError for bad text.
QuickTry plan_quick_try(const QueryParameters& query, std::string_view text, const ModelCatalog& catalog,
                        std::int64_t now_unix_us);

/// `POST /sessions?speak=1`: the body is text for espeak-ng, spoken by a Speak call into the session
/// (its audio then served by /audio). The same parameters, and voice (an espeak-ng voice). Throws
/// QuickTryError for a bad parameter; the text is checked by Speak.
v1::SpeakRequest plan_quick_speak(const QueryParameters& query, std::string_view text, std::int64_t now_unix_us);

/// `GET /listen` (a WebSocket): a live voice from the page, as the settings of one Listen call.
/// Parameters: session (default "mic-" and 8 random hex digits), rate (the pieces' sample rate,
/// 8000 to 48000, required), channels (1 or 2, default 1), latency_ms (the budget, 100 to 2000;
/// default Listen's), transcript (the words that will be spoken, optional), voice, model, fps,
/// visemes, and the media-clock anchor: utterance_zero_us (the "unix" µs at which the first sample
/// was heard; the page sends it) or else lead_ms after the request (default 0). Throws
/// QuickTryError for a bad parameter; the rest is checked by Listen.
v1::ListenSettings plan_page_listen(const QueryParameters& query, std::int64_t now_unix_us);

}  // namespace lipsync::server
