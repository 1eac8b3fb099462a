// Quantiles, with the one rank rule everything in lipdrive uses: calibration percentiles,
// medians of neutral captures, latency figures (--stats, the latency histogram) and the
// fit demo's timing.
//
// The rule is the nearest rank (Hyndman & Fan 1996, definition 1; the inverse of the
// empirical distribution function): the p-quantile of n values is the smallest value v such
// that at least a fraction p of the values are <= v, i.e. the value of 1-based rank
// max(1, ceil(p n)) in ascending order. It always returns one of the values (no
// interpolation), so it applies unchanged to the bins of a histogram, and the median of an
// even count is the lower of the two middle values.
#pragma once

#include <cstddef>
#include <span>

namespace lipdrive {

/// The 1-based rank of the p-quantile among n values (n >= 1, p in [0, 1]): max(1, ceil(p n)).
std::size_t nearest_rank(double p, std::size_t n);

/// The p-quantile of `values` by nearest_rank(); NaN when there are none. Reorders `values`
/// (a partial sort in place), allocates nothing.
double quantile(std::span<double> values, double p);

/// quantile(values, 0.5).
double median(std::span<double> values);

}  // namespace lipdrive
