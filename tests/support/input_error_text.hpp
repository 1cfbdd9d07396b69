// The message of the InputError a call throws, for tests that check what an error names.
#pragma once

#include <string>

#include "lipsync/error.hpp"

namespace lipsync::testing {

/// What `call()` throws as an InputError, or "(no error)" when it returns.
template <typename Call>
std::string error_of(Call call) {
  try {
    call();
  } catch (const InputError& error) {
    return error.what();
  }
  return "(no error)";
}

}  // namespace lipsync::testing
