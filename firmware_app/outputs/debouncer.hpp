// Turns the sampled level of a mechanical button or switch into presses and a steady level.
//
// It lives beside the GPIO output rather than in drivers/ (thin wrappers over hardware) or
// core/ (the face method): it is the daemon's definition of what counts as a press, pure
// computation over (level, time) samples, so tests feed it exact timings.
//
// A change of level counts once it has held for the debounce time; a press is reported
// once, on the accepted change to active. The level seen first is taken as the starting
// state, so a button held down while the daemon starts is not a press.
#pragma once

#include <cstdint>

namespace lipdrive {

class Debouncer {
 public:
  explicit Debouncer(std::int64_t debounce_ns) : debounce_ns_(debounce_ns) {}

  /// One sample: `active` is the button's level, `now_ns` a monotonic time not before the
  /// previous sample's. True exactly once per press.
  bool press(bool active, std::int64_t now_ns) {
    if (!started_) {
      started_ = true;
      stable_ = candidate_ = active;
      return false;
    }
    if (active != candidate_) {
      candidate_ = active;
      candidate_since_ns_ = now_ns;
    }
    if (candidate_ == stable_ || now_ns - candidate_since_ns_ < debounce_ns_) return false;
    stable_ = candidate_;
    return stable_;
  }

  /// The accepted level: the first sample's, then each change once it has held.
  bool level() const { return stable_; }

  /// Forgets the level: the next sample is a new starting state (after the line was lost).
  void reset() { started_ = false; }

 private:
  std::int64_t debounce_ns_;
  bool started_ = false;
  bool stable_ = false;     // the accepted level
  bool candidate_ = false;  // the latest level seen, accepted once it has held long enough
  std::int64_t candidate_since_ns_ = 0;
};

}  // namespace lipdrive
