// A log line that a peer can make the daemon repeat (a malformed datagram, a command, a refused
// request) goes to the journal at most `burst` times a second, the next one with the count of
// those held back meanwhile: an operator's commands are all logged, and a sender gone wrong,
// thousands of datagrams a second, costs a few lines a second, not a core and the disk.
//
// Thread model: any thread (a mutex; the lines it guards are not on the frame path).
#pragma once

#include "drivers/clock.hpp"

#include <spdlog/spdlog.h>

#include <cstdint>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>

namespace lipdrive {

class LogThrottle {
 public:
  explicit LogThrottle(int burst = 10) : burst_(burst) {}

  /// Whether this occurrence is logged; when it is, `held_back` is how many were not since the
  /// last one that was.
  bool pass(std::uint64_t& held_back) {
    constexpr std::int64_t kWindowNs = 1'000'000'000;
    const std::int64_t now = monotonic_ns();
    std::lock_guard lock(mutex_);
    if (now - window_start_ns_ >= kWindowNs) window_start_ns_ = now, logged_in_window_ = 0;
    if (logged_in_window_ >= burst_) {
      ++held_back_;
      return false;
    }
    ++logged_in_window_;
    held_back = std::exchange(held_back_, 0);
    return true;
  }

  /// When the owner stops: the count held back since the last line let through, which no later
  /// line will carry ("WHAT: N more held back in its last second"); nothing when none was.
  void log_held_back(std::string_view what) {
    std::uint64_t held = 0;
    {
      std::lock_guard lock(mutex_);
      held = std::exchange(held_back_, 0);
    }
    if (held > 0) spdlog::warn("{}: {} more held back in its last second", what, held);
  }

 private:
  const int burst_;
  std::mutex mutex_;
  std::int64_t window_start_ns_ = 0;
  int logged_in_window_ = 0;
  std::uint64_t held_back_ = 0;
};

/// A note for a logged line after `held_back` were held back ("" for none).
inline std::string held_back_note(std::uint64_t held_back) {
  return held_back == 0 ? std::string() : ", and " + std::to_string(held_back) + " more held back since the last";
}

}  // namespace lipdrive
