// The per-frame fitter (docs/method.md 3): an affine camera by the Gold Standard
// algorithm and a regularised linear shape fit, alternated a fixed number of times.
// All per-frame arithmetic runs on compile-time sized Eigen matrices, so a fit
// allocates nothing and costs the same every frame.
#pragma once

#include "core/landmarks.hpp"
#include "core/morphable_model.hpp"

#include <Eigen/Core>

#include <memory>

namespace lipdrive {

/// Component counts above this are truncated: the fitter's matrices have compile-time sizes.
inline constexpr int kMaxFitComponents = 40;

struct FitSettings {
  int iterations = 3;     // pose <-> shape alternations per frame (>= 1)
  double lambda = 1.0;    // shape regulariser; 1 = MAP estimate under the prior alpha ~ N(0, I)
  double sigma_px = 1.0;  // landmark noise standard deviation in pixels
};

/// Fixed size: no allocation when reused frame to frame.
struct FitOutput {
  Eigen::Matrix<double, 3, 4> camera;                        // affine camera, last row 0 0 0 1: image = camera * [X;1]
  Eigen::Matrix<double, kMaxFitComponents, 1> coefficients;  // alpha (first num_components used); also the warm start
  Landmarks2D projected;                                     // all 68 model landmarks projected (NaN if unmapped)
  Eigen::Matrix<double, 3, kNumLandmarks>
      model_landmarks;           // fitted shape at the 68 landmark vertices (mm, NaN if unmapped)
  double reprojection_error_px;  // RMS over the landmarks of the set
};

/// The interface of FixedSizeFitter<L, K> (fitting.cpp), one per landmark set and size.
class FitterBase {
 public:
  virtual ~FitterBase() = default;
  virtual void fit(const Landmarks2D& detected, FitOutput& inout) const = 0;
};

class Fitter {
 public:
  /// Precomputes everything that does not change per frame. Throws std::invalid_argument
  /// when a landmark of `set` is unmapped in the model, the model has no components,
  /// or the settings are out of range (iterations < 1, lambda <= 0, sigma_px <= 0).
  Fitter(const MorphableModel& model, LandmarkSet set, FitSettings settings = {});

  /// Fits the model to the detected landmarks of the set (the others are ignored),
  /// warm-started from inout.coefficients. Allocates nothing.
  void fit(const Landmarks2D& detected, FitOutput& inout) const;

  /// Zero coefficients (the mean shape); everything else NaN until the first fit.
  static FitOutput initial_output();

  int num_components() const { return num_components_; }
  /// True when the model has more than kMaxFitComponents components and the rest are ignored.
  bool truncated_components() const { return truncated_; }

 private:
  std::unique_ptr<FitterBase> impl_;  // virtual dispatch to FixedSizeFitter<L, K>
  int num_components_;
  bool truncated_;
};

}  // namespace lipdrive
