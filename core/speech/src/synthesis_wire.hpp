// The bytes between the asking process and a synthesis worker: the request (text, voice, rate) on
// the worker's standard input, and its answer (the synthesis, or the error it threw) on its
// standard output. Both ends are the same program on the same host, so integers travel in the
// machine's own byte order.
#pragma once

#include <string>
#include <string_view>

#include "lipsync/speech/synthesizer.hpp"

namespace lipsync::speech::detail {

struct SynthesisRequest {
  std::string text;
  SynthesisOptions options;
};

/// The request: the text, the voice, the rate.
std::string encode_request(std::string_view text, const SynthesisOptions& options);
/// What encode_request() wrote; std::runtime_error if it is cut short.
SynthesisRequest decode_request(std::string_view bytes);

/// An answer: [kind byte] then, for a synthesis, its phone set, rate, samples, intervals, word
/// starts and notes; for an error, its message.
std::string encode_answer(const Synthesis& synthesis);
/// The answer for an InputError (`message`: InputError::message()), thrown again as one by
/// decode_answer().
std::string encode_input_error_answer(const std::string& message);
/// The answer for any other failure, thrown again as a std::runtime_error "espeak-ng: <message>".
std::string encode_other_error_answer(const std::string& message);
/// The synthesis in what an encode_*answer() wrote, or its error thrown again; std::runtime_error if
/// the answer is cut short.
Synthesis decode_answer(std::string_view bytes);

}  // namespace lipsync::speech::detail
