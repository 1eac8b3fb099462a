// The one clock of the frame path: CLOCK_MONOTONIC, in which every Frame::capture_time_ns,
// latency and deadline is expressed, a stopwatch on it for per-stage timings, and its
// conversion to wall-clock time (OSC time tags, time-of-day timecode).
#pragma once

#include <cstdint>
#include <ctime>

namespace lipdrive {

/// CLOCK_MONOTONIC in nanoseconds.
inline std::int64_t monotonic_ns() {
  timespec now{};
  ::clock_gettime(CLOCK_MONOTONIC, &now);
  return std::int64_t{now.tv_sec} * 1'000'000'000 + now.tv_nsec;
}

/// The wall-clock time (CLOCK_REALTIME, ns since the Unix epoch) of a monotonic_ns() reading:
/// the reading plus the offset between the two clocks now. NTP slewing moves the offset
/// slowly; a step of the wall clock moves it at once, and only later readings see the step.
inline std::int64_t wall_time_ns(std::int64_t monotonic) {
  timespec wall{}, now{};
  ::clock_gettime(CLOCK_REALTIME, &wall);
  ::clock_gettime(CLOCK_MONOTONIC, &now);
  return monotonic + (std::int64_t{wall.tv_sec} - now.tv_sec) * 1'000'000'000 + (wall.tv_nsec - now.tv_nsec);
}

/// Milliseconds elapsed since a monotonic_ns() reading.
inline double ms_since(std::int64_t start_ns) { return static_cast<double>(monotonic_ns() - start_ns) / 1e6; }

}  // namespace lipdrive
