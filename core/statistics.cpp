#include "core/statistics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace lipdrive {

std::size_t nearest_rank(double p, std::size_t n) {
  return std::max<std::size_t>(1, static_cast<std::size_t>(std::ceil(p * static_cast<double>(n))));
}

double quantile(std::span<double> values, double p) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto k = static_cast<std::ptrdiff_t>(std::min(nearest_rank(p, values.size()), values.size()) - 1);
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[static_cast<std::size_t>(k)];
}

double median(std::span<double> values) { return quantile(values, 0.5); }

}  // namespace lipdrive
