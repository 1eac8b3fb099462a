// The timeline a replayed recording's picture and sound share: the simulated camera and the
// simulated microphone of the same clip read it, so that they stay in step the way a camera
// and a microphone on the same performer do (an outage of one does not hold up the other).
//
// Thread model: any thread; the first call of start_ns() fixes the start.
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

 private:
  std::atomic<std::int64_t> start_{0};
};

}  // namespace lipdrive
