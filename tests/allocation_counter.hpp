// Counts heap allocations for the tests that prove a per-frame path allocates nothing.
// Linking tests/allocation_counter.cpp into a test binary replaces the C allocator's entry
// points (malloc, calloc, realloc, posix_memalign, aligned_alloc, memalign) with counting versions;
// operator new, Eigen and OpenCV all allocate through them. Under AddressSanitizer or
// ThreadSanitizer, whose allocator malloc is, the sanitizer's allocation hook counts instead.
#pragma once

namespace lipdrive::test {

/// Allocations made so far by threads that counted (see count_allocations_on_this_thread).
long allocation_count();

/// Starts or stops counting the calling thread's allocations (off for every thread at start).
void count_allocations_on_this_thread(bool on);

}  // namespace lipdrive::test
