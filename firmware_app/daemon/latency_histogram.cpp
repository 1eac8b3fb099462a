#include "firmware_app/daemon/latency_histogram.hpp"

#include "core/statistics.hpp"

#include <algorithm>
#include <cmath>

namespace lipdrive {

void LatencyHistogram::add(std::int64_t latency_ns) {
  const double ms = static_cast<double>(std::max<std::int64_t>(latency_ns, 0)) / 1e6;
  const auto bin = static_cast<std::int64_t>(ms / kBinMs);
  bins_[static_cast<std::size_t>(std::min<std::int64_t>(bin, kBins - 1))].fetch_add(1, std::memory_order_relaxed);
  count_.fetch_add(1, std::memory_order_relaxed);
}

double LatencyHistogram::quantile_ms(double p) const {
  std::array<std::uint64_t, kBins> counts{};
  std::uint64_t total = 0;
  for (int i = 0; i < kBins; ++i) total += counts[i] = bins_[i].load(std::memory_order_relaxed);
  if (total == 0) return std::nan("");
  const std::uint64_t rank = nearest_rank(p, total);
  std::uint64_t seen = 0;
  for (int i = 0; i < kBins; ++i) {
    seen += counts[i];
    if (seen >= rank) return (i + 1) * kBinMs;
  }
  return kBins * kBinMs;
}

}  // namespace lipdrive
