// Errors for bad input: a model file, an utterance file, a phoneme stream.
//
// Every problem found at the edge is reported once, as an InputError that says
// where (source name, 1-based line or phoneme index, field) and what was wrong,
// so that a user can fix the input without reading our code.
#pragma once

#include <stdexcept>
#include <string>

namespace lipsync {

class InputError : public std::runtime_error {
 public:
  /// `source`: file name, "<stdin>" or "phoneme stream"; `line`: 1-based line (or
  /// phoneme index) or 0 when unknown; `message`: what is wrong, naming the value.
  InputError(std::string source, int line, std::string message);

  const std::string& source() const noexcept { return source_; }
  int line() const noexcept { return line_; }
  /// The message without the "source:line: " prefix.
  const std::string& message() const noexcept { return message_; }

 private:
  std::string source_;
  int line_;
  std::string message_;
};

}  // namespace lipsync
