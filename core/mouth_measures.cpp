#include "core/mouth_measures.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace lipdrive {

MouthReference mouth_reference(const MorphableModel& model, const Eigen::VectorXf& identity,
                               std::span<const double> rest) {
  // The model-space measures read these landmarks; one unmapped would make them NaN on every frame.
  for (const int landmark :
       {ibug::kNoseTip, ibug::kRightEyeInner, ibug::kLeftEyeInner, ibug::kOuterLipTop, ibug::kInnerCornerRight,
        ibug::kInnerLipTop, ibug::kInnerCornerLeft, ibug::kInnerLipBottom}) {
    const int mapped = model.landmark_vertex[landmark];
    if (mapped < 0 || mapped >= model.num_vertices())
      throw std::invalid_argument("the model does not map landmark " + std::to_string(landmark) +
                                  " to a vertex (the mouth measures read landmarks 30, 39, 42, 51, 60, 62, 64 and 66)");
  }
  const int vertex = model.landmark_vertex[ibug::kOuterLipTop];
  const auto neutral = model.pose_index("neutral");
  const Eigen::VectorXf shape = neutral               ? model.shape(model.pose_coefficients.col(*neutral))
                                : identity.size() > 0 ? model.shape(identity)
                                                      : Eigen::VectorXf(model.mean);
  double z = shape(3 * vertex + 2);
  const std::size_t shapes = std::min(rest.size(), static_cast<std::size_t>(model.num_expressions()));
  for (std::size_t e = 0; e < shapes; ++e)
    z += rest[e] * model.expressions(3 * vertex + 2, static_cast<Eigen::Index>(e));
  return MouthReference{z};
}

double fit_quality(double reprojection_error_px, double d_px) {
  const double relative = reprojection_error_px / (0.15 * d_px);
  const double quality = 1.0 / (1.0 + relative * relative);
  return std::isfinite(quality) ? quality : 0.0;
}

MouthMeasures measure_mouth(const Landmarks2D& tracked, const FitOutput& fit, const MouthReference& reference) {
  const MouthRatios image = mouth_ratios<2>(tracked);
  const MouthRatios projected = mouth_ratios<2>(fit.projected);
  const MouthRatios model = mouth_ratios<3>(fit.model_landmarks);
  MouthMeasures m;
  m.width_2d = image.width;
  m.height_2d = image.height;
  m.width_fit = projected.width;
  m.height_fit = projected.height;
  m.width_3d = model.width;
  m.height_3d = model.height;
  m.protrusion_3d = (fit.model_landmarks(2, ibug::kOuterLipTop) - reference.neutral_upper_lip_z) / model.d;
  m.quality = fit_quality(fit.reprojection_error_px, image.d);
  m.open = m.height_2d;
  return m;
}

}  // namespace lipdrive
