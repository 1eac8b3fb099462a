#include "core/facial_indices.hpp"

#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace lipdrive {

FacialMeasures facial_measures(const Landmarks2D& landmarks) {
  FacialMeasures m;
  for (int i = 0; i < kNumFacialDistances; ++i)
    m.distances[i] = (landmarks.col(kFacialDistances[i].from) - landmarks.col(kFacialDistances[i].to)).norm();
  for (int i = 0; i < kNumFacialIndices; ++i)
    m.indices[i] = 100 * m.distances[kFacialIndices[i].smaller] / m.distances[kFacialIndices[i].larger];
  return m;
}

Landmarks2D frontal_neutral_landmarks(const MorphableModel& model) {
  const auto neutral = model.pose_index("neutral");
  const Eigen::VectorXf shape =
      neutral ? model.shape(model.pose_coefficients.col(*neutral)) : Eigen::VectorXf(model.mean);
  Landmarks2D out = Landmarks2D::Constant(std::nan(""));
  for (const FacialDistanceDefinition& d : kFacialDistances)
    for (const int landmark : {d.from, d.to}) {
      const int vertex = model.landmark_vertex[landmark];
      if (vertex < 0 || vertex >= model.num_vertices())
        throw std::invalid_argument("the model does not map landmark " + std::to_string(landmark) +
                                    ", which the facial indices need");
      out.col(landmark) = shape.segment<2>(3 * vertex).cast<double>();
    }
  return out;
}

std::string_view index_class_name(IndexClass c) {
  switch (c) {
    case IndexClass::kLow: return "low";
    case IndexClass::kMiddle: return "middle";
    case IndexClass::kHigh: return "high";
  }
  return "?";
}

IndexClass classify(double index, ClassThresholds thresholds) {
  if (index < thresholds.low_below) return IndexClass::kLow;
  if (index > thresholds.high_above) return IndexClass::kHigh;
  return IndexClass::kMiddle;
}

MouthClasses mouth_classes(const FacialMeasures& measures) {
  return {classify(measures.indices[kVerticalMouthHeightIndex], kVerticalMouthHeightClasses),
          classify(measures.indices[kMouthWidthIndex], kMouthWidthClasses)};
}

Compatibility compatibility(const FacialMeasures& performer, const FacialMeasures& model) {
  Compatibility c{mouth_classes(performer), mouth_classes(model)};
  c.warn = std::abs(static_cast<int>(c.performer.vertical_mouth_height) -
                    static_cast<int>(c.model.vertical_mouth_height)) == 2;
  return c;
}

}  // namespace lipdrive
