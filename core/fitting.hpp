// The per-frame fitter (docs/method.md 3): an affine camera by the Gold Standard
// algorithm and a linear shape fit, alternated a fixed number of times. One interface for
// both kinds of model: a pose-PCA model fits its components (regularised least squares); a
// model with expression shapes (the ICT head) fits the expression weights in [0, 1] (bounded
// least squares) on the performer's identity, which fit_identity() fits once from neutral frames.
// All per-frame arithmetic runs on compile-time sized Eigen matrices, so a fit
// allocates nothing and costs the same every frame.
#pragma once

#include "core/landmarks.hpp"
#include "core/morphable_model.hpp"

#include <Eigen/Core>

#include <memory>
#include <span>
#include <string_view>

namespace lipdrive {

/// Component counts above this are truncated: the fitter's matrices have compile-time sizes.
inline constexpr int kMaxFitComponents = 40;
/// The most expression shapes a model may have (the ICT head has 53).
inline constexpr int kMaxFitExpressions = 56;

struct FitSettings {
  int iterations = 10;    // pose <-> shape alternations per frame (>= 1; docs/method.md 3 says why 10)
  double lambda = 1.0;    // shape regulariser; 1 = MAP estimate under the prior alpha ~ N(0, I)
  double sigma_px = 1.0;  // landmark noise standard deviation in pixels
  // Expression models (docs/method.md 3):
  int sweeps = 4;                     // coordinate-descent sweeps per pose <-> shape iteration (>= 1)
  int identity_iterations = 10;       // fit_identity: camera <-> identity alternations (>= 1)
  double expression_sigma_mm = 1.0;   // landmark noise on the face, in mm (the residual over the camera scale)
  double expression_prior = 0.0;      // lambda_e: a Gaussian prior, cost 1/2 lambda_e w^2, in units of sigma^2
  double expression_sparsity = 0.75;  // mu_e: a sparse (L1) prior, cost mu_e w (docs/arkit.md "A sparse prior")
  double jaw_prior_ratio = 1.0;       // lambda_e and mu_e of jawOpen and mouthClose relative to the others
};

/// Expression shapes a 68-point landmark fit cannot observe (eye gaze, a puffed cheek, the
/// tongue): the fit holds them at 0.
bool is_unobservable_expression(std::string_view name);

/// Fixed size: no allocation when reused frame to frame.
struct FitOutput {
  Eigen::Matrix<double, 3, 4> camera;                        // affine camera, last row 0 0 0 1: image = camera * [X;1]
  Eigen::Matrix<double, kMaxFitComponents, 1> coefficients;  // alpha (first num_components used); also the warm start
  using Expressions = Eigen::Matrix<double, kMaxFitExpressions, 1>;
  Expressions
      expressions;        // expression weights in [0, 1] in the model's order (0 for a pose-PCA model); the warm start
  Landmarks2D projected;  // all 68 model landmarks projected (NaN if unmapped)
  Eigen::Matrix<double, 3, kNumLandmarks>
      model_landmarks;           // fitted shape at the 68 landmark vertices (mm, NaN if unmapped)
  double reprojection_error_px;  // RMS over the landmarks of the set
};

/// The interface of FixedSizeFitter<L, K> (fitting.cpp), one per landmark set and size.
class FitterBase {
 public:
  virtual ~FitterBase() = default;
  virtual void fit(const Landmarks2D& detected, FitOutput& inout) const = 0;
  /// Adds one frame's A^T A and A^T b of the shape fit at coefficients `alpha`, under the
  /// frame's camera for that shape (fit_identity).
  virtual void add_normal_equations(const Landmarks2D& detected, const Eigen::VectorXd& alpha, Eigen::MatrixXd& AtA,
                                    Eigen::VectorXd& Atb) const = 0;
};

class Fitter {
 public:
  /// Precomputes everything that does not change per frame. Throws std::invalid_argument
  /// when a landmark of `set` is unmapped in the model, the model has no components,
  /// or the settings are out of range (iterations < 1, lambda <= 0, sigma_px <= 0). For a
  /// model with expression shapes, `identity` is the performer's (fit_identity; empty = the
  /// mean face) and `set` must be F4 or F5.
  Fitter(const MorphableModel& model, LandmarkSet set, FitSettings settings = {},
         const Eigen::VectorXf& identity = Eigen::VectorXf());

  /// Fits the model to the detected landmarks of the set (the others are ignored),
  /// warm-started from inout.coefficients (inout.expressions for an expression model).
  /// Allocates nothing.
  void fit(const Landmarks2D& detected, FitOutput& inout) const;

  /// Zero coefficients (the mean shape); everything else NaN until the first fit.
  static FitOutput initial_output();

  int num_components() const { return num_components_; }
  /// True when the model has more than kMaxFitComponents components and the rest are ignored.
  bool truncated_components() const { return truncated_; }
  /// True for a model with expression shapes: the fit sets FitOutput::expressions.
  bool fits_expressions() const { return expressions_; }

 private:
  std::unique_ptr<FitterBase> impl_;  // virtual dispatch to FixedSizeFitter<L, K>
  int num_components_;
  bool truncated_;
  bool expressions_;
};

/// The identity of a performer from neutral frames (docs/method.md 3): the components alpha of
/// one shape behind all frames, each frame under its own affine camera, alternated `iterations`
/// times (MAP estimate, the data term summed over the frames). For a model with expression
/// shapes, these are its identity components, fitted with the expressions at 0. Throws
/// std::invalid_argument as Fitter does, or when `frames` is empty. Allocates: calibration only.
Eigen::VectorXf fit_identity(const MorphableModel& model, LandmarkSet set, std::span<const Landmarks2D> frames,
                             FitSettings settings = {});

/// The performer's rest point (docs/arkit.md, "The performer's rest point"): the expression
/// weights the fit gives the neutral frames on the performer's identity, per shape the median
/// over the frames. What no
/// identity explains on this face (the landmark detector's own bias, the model's landmark
/// definitions) lands in these weights. The frames are fitted in order, warm-started, and
/// repeated until at least kRestWarmUpFits fits have run (from the mean face the fit converges
/// over tens of frames); the median is taken over the last pass. jawOpen and mouthClose keep a
/// rest of 0: they are the mouth's opening, whose rest is the closed mouth (a bilabial closure
/// presses below the relaxed neutral; subtracting their neutral weight lost the closures'
/// part of the opening, docs/arkit.md). Allocates: calibration only.
FitOutput::Expressions fit_rest_expression(const MorphableModel& model, LandmarkSet set,
                                           std::span<const Landmarks2D> frames, const Eigen::VectorXf& identity,
                                           FitSettings settings = {});
inline constexpr int kRestWarmUpFits = 60;

/// The expression weights `w` relative to the performer's rest point `rest` (fit_rest_expression):
/// per shape (w - rest) / (1 - rest), clamped to [0, 1], so the rest reads 0 and a full shape 1.
/// A zero rest leaves the weight as it is (mouthClose <= jawOpen holds as fitted). Allocates nothing.
void above_rest(const FitOutput::Expressions& w, const FitOutput::Expressions& rest, FitOutput::Expressions& out);

}  // namespace lipdrive
