// (d) Fitter::fit allocates nothing: this binary replaces the global operator new/delete
// and the C allocator (Eigen allocates through malloc, not new) with counting versions.
#include "core/fitting.hpp"
#include "reference_fitter.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

namespace {
std::atomic<long> g_allocations{0};
}  // namespace

// glibc's own entry points, which its malloc/free are aliases of.
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* pointer, std::size_t size);
void __libc_free(void* pointer);

void* malloc(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return __libc_calloc(count, size);
}
void* realloc(void* pointer, std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  return __libc_realloc(pointer, size);
}
void free(void* pointer) { __libc_free(pointer); }
}

void* operator new(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* pointer = __libc_malloc(size == 0 ? 1 : size)) return pointer;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, std::align_val_t alignment) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  void* pointer = nullptr;
  if (posix_memalign(&pointer, static_cast<std::size_t>(alignment), size == 0 ? 1 : size) == 0) return pointer;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t alignment) { return operator new(size, alignment); }
void operator delete(void* pointer) noexcept { __libc_free(pointer); }
void operator delete[](void* pointer) noexcept { __libc_free(pointer); }
void operator delete(void* pointer, std::size_t) noexcept { __libc_free(pointer); }
void operator delete[](void* pointer, std::size_t) noexcept { __libc_free(pointer); }
void operator delete(void* pointer, std::align_val_t) noexcept { __libc_free(pointer); }
void operator delete[](void* pointer, std::align_val_t) noexcept { __libc_free(pointer); }
void operator delete(void* pointer, std::size_t, std::align_val_t) noexcept { __libc_free(pointer); }
void operator delete[](void* pointer, std::size_t, std::align_val_t) noexcept { __libc_free(pointer); }

namespace lipdrive {
namespace {

TEST(FitAllocations, CounterCountsNewAndMalloc) {
  const long before = g_allocations.load();
  int* volatile object = new int(1);  // volatile: the allocation may not be elided
  delete object;
  EXPECT_EQ(g_allocations.load() - before, 1);
  void* volatile block = std::malloc(64);
  std::free(block);
  EXPECT_EQ(g_allocations.load() - before, 2);
}

TEST(FitAllocations, FitAllocatesNothing) {
  for (const int components : {12, 40}) {  // both compiled sizes
    for (const LandmarkSet set : {LandmarkSet::F1, LandmarkSet::F2, LandmarkSet::F3, LandmarkSet::F4, LandmarkSet::F5}) {
      SCOPED_TRACE(::testing::Message() << landmark_set_name(set) << ", K = " << components);
      const MorphableModel model = testing::random_model(100, components, 1);
      const Landmarks2D landmarks = testing::project(
          testing::test_camera(1.5), testing::model_landmarks(model, testing::random_coefficients(components, 2)));
      const Fitter fitter(model, set);
      FitOutput output = Fitter::initial_output();

      const long before = g_allocations.load();
      for (int frame = 0; frame < 100; ++frame) fitter.fit(landmarks, output);
      const long allocations = g_allocations.load() - before;

      EXPECT_EQ(allocations, 0);
      EXPECT_TRUE(std::isfinite(output.reprojection_error_px));  // the fits did run
    }
  }
}

}  // namespace
}  // namespace lipdrive
