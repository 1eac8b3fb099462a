// Which sanitizer this test binary is built with (scripts/sanitize.sh builds with clang, whose
// __has_feature tells; gcc sets __SANITIZE_ADDRESS__ / __SANITIZE_THREAD__):
// LIPDRIVE_ADDRESS_SANITIZER or LIPDRIVE_THREAD_SANITIZER is defined to 1, or neither.
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define LIPDRIVE_ADDRESS_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define LIPDRIVE_ADDRESS_SANITIZER 1
#endif
#endif

#if defined(__SANITIZE_THREAD__)
#define LIPDRIVE_THREAD_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define LIPDRIVE_THREAD_SANITIZER 1
#endif
#endif
