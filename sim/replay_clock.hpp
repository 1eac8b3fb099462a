// The timeline a replayed recording's picture and sound share: the simulated camera and the
// simulated microphone of the same clip read it, so that they stay in step the way a camera
// and a microphone on the same performer do (an outage of one does not hold up the other).
//
// Thread model: any thread; the first call of start_ns() fixes the start. The loop's length is
// set by the camera as it opens the recording, before the sound is opened.
#pragma once

#include "drivers/clock.hpp"

#include <atomic>
#include <cstdint>

namespace lipdrive {

class ReplayClock {
 public:
  /// CLOCK_MONOTONIC of the recording's time 0: the moment of the first call.
  std::int64_t start_ns() {
    std::int64_t start = start_.load(std::memory_order_acquire);
    if (start != 0) return start;
    const std::int64_t now = monotonic_ns();
    return start_.compare_exchange_strong(start, now, std::memory_order_acq_rel) ? now : start;
  }

  /// One pass of a looping replay, in seconds (SimulatedCamera::duration_s()); 0 when the
  /// recording plays once: the sound loops at it too.
  void set_loop_s(double seconds) { loop_s_.store(seconds, std::memory_order_release); }
  double loop_s() const { return loop_s_.load(std::memory_order_acquire); }

 private:
  std::atomic<std::int64_t> start_{0};
  std::atomic<double> loop_s_{0};
};

}  // namespace lipdrive
