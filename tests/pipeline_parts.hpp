// What the tests of the frame path share: a frame processor on the default model with the
// shared predictor, and the sink that starts counting the processing thread's allocations
// once the pipeline has warmed up (tests/allocation_counter.cpp must be linked).
#pragma once

#include "allocation_counter.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "firmware_app/daemon/frame_result.hpp"
#include "fixture_paths.hpp"
#include "shared_predictor.hpp"

#include <atomic>
#include <memory>

namespace lipdrive::test {

inline std::unique_ptr<FrameProcessor> make_processor() {
  static const MorphableModel model = load_model_file(kModel);
  return std::make_unique<FrameProcessor>(model, kDefaultLandmarkSet, FitSettings{}, shared_predictor());
}

/// Counts the processing thread's allocations from its kWarmUp-th result on.
class AllocationWatch : public ResultSink {
 public:
  void push(const FrameResult&) override {
    if (++frames == kWarmUp) count_allocations_on_this_thread(true);
  }
  static constexpr int kWarmUp = 30;
  std::atomic<int> frames{0};
};

}  // namespace lipdrive::test
