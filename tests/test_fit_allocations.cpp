// (d) Fitter::fit allocates nothing (allocations counted by tests/allocation_counter.cpp).
#include "allocation_counter.hpp"
#include "core/fitting.hpp"
#include "reference_fitter.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

namespace lipdrive {
namespace {

TEST(FitAllocations, CounterCountsNewAndMalloc) {
  test::count_allocations_on_this_thread(true);
  const long before = test::allocation_count();
  int* volatile object = new int(1);  // volatile: the allocation may not be elided
  delete object;
  EXPECT_EQ(test::allocation_count() - before, 1);
  void* volatile block = std::malloc(64);
  std::free(block);
  EXPECT_EQ(test::allocation_count() - before, 2);
}

TEST(FitAllocations, FitAllocatesNothing) {
  test::count_allocations_on_this_thread(true);
  for (const int components : {12, 40}) {  // both compiled sizes
    for (const LandmarkSet set :
         {LandmarkSet::F1, LandmarkSet::F2, LandmarkSet::F3, LandmarkSet::F4, LandmarkSet::F5}) {
      SCOPED_TRACE(::testing::Message() << landmark_set_name(set) << ", K = " << components);
      const MorphableModel model = testing::random_model(100, components, 1);
      const Landmarks2D landmarks = testing::project(
          testing::test_camera(1.5), testing::model_landmarks(model, testing::random_coefficients(components, 2)));
      const Fitter fitter(model, set);
      FitOutput output = Fitter::initial_output();

      const long before = test::allocation_count();
      for (int frame = 0; frame < 100; ++frame) fitter.fit(landmarks, output);
      const long allocations = test::allocation_count() - before;

      EXPECT_EQ(allocations, 0);
      EXPECT_TRUE(std::isfinite(output.reprojection_error_px));  // the fits did run
    }
  }
}

}  // namespace
}  // namespace lipdrive
