// Whether a test runs under a sanitizer, for the few measures whose bounds are the product build's
// (resident memory, time): ThreadSanitizer keeps a shadow of the heap and instruments every
// destructor and thread exit, so those bounds either scale or hold only without it.
#pragma once

namespace lipsync::testing {

#if defined(__SANITIZE_THREAD__)
inline constexpr bool kUnderThreadSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
inline constexpr bool kUnderThreadSanitizer = true;
#else
inline constexpr bool kUnderThreadSanitizer = false;
#endif
#else
inline constexpr bool kUnderThreadSanitizer = false;
#endif

}  // namespace lipsync::testing
