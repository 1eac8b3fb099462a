// Agreement between a ground-truth series and an output series (docs/method.md 5).
#pragma once

#include <span>

namespace lipdrive {

/// How well an output series ẑ follows a ground-truth series z over the same frames.
/// Every field is NaN when no pair was usable.
struct SeriesAgreement {
  int pairs_used = 0;        // frames where both z and ẑ are finite
  double rmse_scaled = 0;    // RMSE after min–max scaling each series to [0, 1]
  double mae = 0;            // mean absolute error, raw units
  double max_abs_error = 0;  // largest absolute error, raw units
  double pearson_r = 0;      // NaN when either series is constant
  double std_ratio = 0;      // σ(ẑ)/σ(z); NaN when z is constant
};

/// Compares `output` with `truth` element by element; pairs where either value is
/// NaN (e.g. an untracked frame) are skipped. The min–max scaled RMSE compares shape
/// and timing independently of units and gain; a constant series has no range and
/// scales to all zeros (scikit-learn's MinMaxScaler convention), so two constant
/// series agree perfectly. The standard-deviation ratio exposes under-articulation
/// (ratio < 1) that smoothing can cause. Throws std::invalid_argument when the
/// series differ in length.
SeriesAgreement compare_series(std::span<const double> truth, std::span<const double> output);

}  // namespace lipdrive
