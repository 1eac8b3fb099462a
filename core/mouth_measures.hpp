// Mouth measures per frame (docs/method.md 4): inner-lip width and height over a
// speech-independent face size, from the tracked landmarks, from the fitted model's
// projection, and in model space; upper-lip protrusion from the fitted 3D shape.
#pragma once

#include "core/fitting.hpp"
#include "core/landmarks.hpp"
#include "core/morphable_model.hpp"

#include <Eigen/Core>

#include <span>

namespace lipdrive {

/// Width and height of the inner lips, each over the normaliser d.
struct MouthRatios {
  double width = 0;   // |p60 - p64| / d
  double height = 0;  // |p62 - p66| / d
  double d = 0;       // |midpoint(p39, p42) - p30|: inner eye corners to nose tip, not moved by speech
};

/// docs/method.md 4 on 2D (image) or 3D (model space) landmarks.
template <int Dim>
MouthRatios mouth_ratios(const Eigen::Matrix<double, Dim, kNumLandmarks>& p) {
  MouthRatios r;
  r.d = (0.5 * (p.col(ibug::kRightEyeInner) + p.col(ibug::kLeftEyeInner)) - p.col(ibug::kNoseTip)).norm();
  r.width = (p.col(ibug::kInnerCornerRight) - p.col(ibug::kInnerCornerLeft)).norm() / r.d;
  r.height = (p.col(ibug::kInnerLipTop) - p.col(ibug::kInnerLipBottom)).norm() / r.d;
  return r;
}

/// What protrusion is measured against: the upper-lip midpoint's depth at rest.
struct MouthReference {
  double neutral_upper_lip_z = 0;  // model z (mm, out of the face) of landmark 51 in the neutral pose
};

/// The reference of a model: its pose named "neutral", or else the mean shape moved by the
/// performer's `identity` (Fitter's; empty = the mean face) and, for a model with expression
/// shapes, by the weights of the performer's rest point (`rest`, the model's order; empty =
/// none), so that the performer's rest measures protrusion 0. Throws std::invalid_argument when
/// a landmark measure_mouth() reads from the model (30, 39, 42, 51, 60, 62, 64, 66) is unmapped.
MouthReference mouth_reference(const MorphableModel& model, const Eigen::VectorXf& identity = Eigen::VectorXf(),
                               std::span<const double> rest = {});

struct MouthMeasures {
  double width_2d = 0, height_2d = 0;    // tracked landmarks
  double width_fit = 0, height_fit = 0;  // the fit's projected model landmarks
  double width_3d = 0, height_3d = 0;    // the fitted shape in model space
  double protrusion_3d = 0;              // (z51 - neutral z51) / d_3d: positive = lips pushed forward
  double quality = 0;                    // fit_quality(): 1 = the fit explains the landmarks exactly
  /// Lip contact (core/lip_contact.hpp), from the pixels where the image was seen: seal is the
  /// probability that the lips touch, open the opening that drives the figure (H/d). Without
  /// the image, seal = 0 and open = height_2d.
  double seal = 0;
  double open = 0;
};

/// Confidence in [0, 1] from the fit's RMS reprojection error relative to the face size
/// (d of the tracked landmarks): 1 / (1 + (e / (0.15 d))^2). It is 1 for a perfect fit and
/// 0.5 when the error is 15 % of d (about 5 px on a 360x288 GRID face, where the default
/// model fits real speech to about 12 % of d), falling towards 0 as the landmarks stop
/// looking like the model.
double fit_quality(double reprojection_error_px, double d_px);

/// All measures of one frame. Allocates nothing.
MouthMeasures measure_mouth(const Landmarks2D& tracked, const FitOutput& fit, const MouthReference& reference);

}  // namespace lipdrive
