#include "allocation_counter.hpp"
#include "sanitizer_build.hpp"

#include <atomic>
#include <cerrno>
#include <cstddef>

namespace {
thread_local bool t_counting = false;
std::atomic<long> g_count{0};

void count() {
  if (t_counting) g_count.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

namespace lipdrive::test {
long allocation_count() { return g_count.load(); }
void count_allocations_on_this_thread(bool on) { t_counting = on; }
}  // namespace lipdrive::test

#if defined(LIPDRIVE_ADDRESS_SANITIZER) || defined(LIPDRIVE_THREAD_SANITIZER)
// Under AddressSanitizer or ThreadSanitizer (scripts/sanitize.sh) the sanitizer's allocator
// is malloc and must stay so; its allocation hook, called for every allocation it makes
// (malloc family and operator new alike), counts instead.
#include <sanitizer/allocator_interface.h>

namespace {
void on_allocation(const volatile void*, std::size_t) { count(); }
void on_free(const volatile void*) {}
[[maybe_unused]] const int g_hooks_installed = __sanitizer_install_malloc_and_free_hooks(on_allocation, on_free);
}  // namespace
#else
// glibc's real allocator, which its public malloc family are aliases of (valloc and pvalloc,
// obsolete, are not replaced: nothing the live path links uses them).
extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);

void* malloc(std::size_t size) {
  count();
  return __libc_malloc(size);
}
void* calloc(std::size_t n, std::size_t size) {
  count();
  return __libc_calloc(n, size);
}
void* realloc(void* p, std::size_t size) {
  count();
  return __libc_realloc(p, size);
}
int posix_memalign(void** p, std::size_t alignment, std::size_t size) {
  count();
  *p = __libc_memalign(alignment, size);
  return *p ? 0 : ENOMEM;
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  count();
  return __libc_memalign(alignment, size);
}
// The legacy entry point FFTW's fftwf_malloc uses (through aubio's DCT): uncounted, a
// per-block allocation in the voice path went unseen until the ASan lane's hook saw it.
void* memalign(std::size_t alignment, std::size_t size) {
  count();
  return __libc_memalign(alignment, size);
}
}
#endif
