// The one retry policy for a device or peer that went away (camera, serial line, GPIO chip,
// Modbus slave): exponential back-off. The first retry waits `first`, each failure after it
// doubles the wait up to `max`, and a success resets it.
//
// Pure and header-only: it keeps no clock. The caller asks for the delay after a failure and
// schedules the next attempt on its own clock, so the drivers use it without linking core.
#pragma once

#include <algorithm>
#include <chrono>

namespace lipdrive {

class Backoff {
 public:
  /// `first` is capped at `max`.
  Backoff(std::chrono::nanoseconds first, std::chrono::nanoseconds max) : first_(std::min(first, max)), max_(max) {}

  /// An attempt failed: the delay before the next one (first, 2 first, 4 first, ... max).
  std::chrono::nanoseconds failed() {
    delay_ = delay_.count() == 0 ? first_ : std::min(2 * delay_, max_);
    return delay_;
  }
  /// An attempt succeeded: the next failure starts again at `first`.
  void succeeded() { delay_ = std::chrono::nanoseconds(0); }

  /// The delay failed() last returned; 0 after a success (or before any failure).
  std::chrono::nanoseconds delay() const { return delay_; }
  /// Failing since the last success.
  bool failing() const { return delay_.count() != 0; }
  std::chrono::nanoseconds max() const { return max_; }

 private:
  std::chrono::nanoseconds first_, max_;
  std::chrono::nanoseconds delay_{0};
};

}  // namespace lipdrive
