// Failures to exit statuses, and the end of the process (command_main.hpp).
#include "command_main.hpp"

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>
#include <new>
#include <stdexcept>
#include <string>
#include <string_view>

#include "cli_error.hpp"
#include "lipsync/error.hpp"
#ifdef LIPSYNC_WITH_NETWORK
#include "lipsync/client/animation_client.hpp"
#endif

#if defined(__SANITIZE_ADDRESS__)
#define LIPSYNC_ADDRESS_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define LIPSYNC_ADDRESS_SANITIZER 1
#endif
#endif
#ifdef LIPSYNC_ADDRESS_SANITIZER
#include <sanitizer/lsan_interface.h>
#endif

namespace lipsync::cli {
namespace {

int fail(std::string_view message, int status) {
  std::cerr << "lipsync: error: " << message << '\n';
  return status;
}

}  // namespace

int report_failures(const std::function<int()>& command) {
  try {
    return command();
  } catch (const UsageError& error) {
    return fail(error.what(), kExitUsageError);
  } catch (const lipsync::InputError& error) {
    return fail(error.what(), kExitInputError);
  } catch (const FileError& error) {
    return fail(error.what(), kExitInputError);
#ifdef LIPSYNC_WITH_NETWORK
  } catch (const lipsync::client::CallError& error) {
    return fail(error.what(), kExitInputError);
#endif
  } catch (const std::bad_alloc&) {
    return fail("out of memory", kExitInputError);
  } catch (const std::exception& error) {
    return fail(std::string("internal error: ") + error.what(), kExitInputError);
  }
}

[[noreturn]] void end_process(int status) {
  std::cout.flush();
  std::cerr.flush();
  std::fflush(nullptr);
#ifdef LIPSYNC_ADDRESS_SANITIZER
  __lsan_do_leak_check();  // ends the process with LSan's exit code if something leaked
#endif
  std::_Exit(status);
}

}  // namespace lipsync::cli
