// The one clock of the frame path: CLOCK_MONOTONIC, in which every Frame::capture_time_ns,
// latency and deadline is expressed, and a stopwatch on it for per-stage timings.
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

/// Milliseconds elapsed since a monotonic_ns() reading.
inline double ms_since(std::int64_t start_ns) { return static_cast<double>(monotonic_ns() - start_ns) / 1e6; }

}  // namespace lipdrive
