// Latency distribution with fixed bins: no allocation, one writer, any number of readers.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

namespace lipdrive {

class LatencyHistogram {
 public:
  static constexpr double kBinMs = 0.05;
  static constexpr int kBins = 4000;  // 0..200 ms; the last bin also holds everything slower

  void add(std::int64_t latency_ns);
  /// The upper edge of the bin holding the p-quantile (the rank rule of core/statistics.hpp),
  /// in ms; NaN when empty.
  double quantile_ms(double p) const;
  std::uint64_t count() const { return count_.load(std::memory_order_relaxed); }

 private:
  std::array<std::atomic<std::uint32_t>, kBins> bins_{};
  std::atomic<std::uint64_t> count_{0};
};

}  // namespace lipdrive
