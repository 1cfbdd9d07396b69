// The two kinds of failure the command line reports itself (core input
// problems arrive as lipsync::InputError): a mistake on the command line
// (exit status 2) and a file that cannot be read or written (exit status 1).
#pragma once

#include <stdexcept>

namespace lipsync::cli {

inline constexpr int kExitInputError = 1;
inline constexpr int kExitUsageError = 2;

/// Unknown option, missing or malformed value: names the option and the value.
class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A file that cannot be read, created or renamed: names the file and the reason.
class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace lipsync::cli
