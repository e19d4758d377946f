#pragma once
// Whether this test binary is built with ThreadSanitizer or AddressSanitizer (gcc or clang): there
// every process of a line runs several times slower, and a test holds the bridge to what it must
// do (SYNC comes back, a process returns), not to the figures the normal build is held to.

namespace lb::test {

#if defined(__SANITIZE_THREAD__) || defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer) || __has_feature(address_sanitizer)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif
#else
inline constexpr bool kSanitized = false;
#endif

}  // namespace lb::test
