// The daemon's calibrate command (GPIO button, Modbus register, SIGUSR1): the next N tracked
// frames are captured on the processing thread, then the main thread re-centres the
// performer's profile on them.
#pragma once

#include "core/calibration.hpp"
#include "firmware_app/pipeline.hpp"

#include <atomic>
#include <span>

namespace lipdrive {

class NeutralCapture : public ResultSink {
 public:
  explicit NeutralCapture(int frames) : frames_(frames) {}

  /// Any thread: starts a capture; false while one is already running.
  bool arm() {
    int idle = kIdle;
    return state_.compare_exchange_strong(idle, kArmed);
  }
  /// The capture is complete; samples() is stable until release().
  bool done() const { return state_.load(std::memory_order_acquire) == kDone; }
  std::span<const CalibrationSample> samples() const { return capture_.samples(); }
  void release() { state_.store(kIdle, std::memory_order_release); }

  /// Processing thread. Allocates nothing.
  void push(const FrameResult& result) override {
    int state = state_.load(std::memory_order_acquire);
    if (state == kArmed) {
      capture_.clear();
      state_.store(state = kCapturing, std::memory_order_relaxed);
    }
    if (state != kCapturing || !result.tracked) return;
    capture_.add(result.measures);
    if (capture_.size() >= frames_) state_.store(kDone, std::memory_order_release);
  }

 private:
  enum : int { kIdle, kArmed, kCapturing, kDone };
  CalibrationCapture capture_;
  int frames_;
  std::atomic<int> state_{kIdle};
};

}  // namespace lipdrive
