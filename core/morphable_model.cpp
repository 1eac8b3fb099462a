#include "core/morphable_model.hpp"

#include <algorithm>

namespace lipdrive {
namespace {

std::optional<int> index_of(const std::vector<std::string>& names, std::string_view name) {
  const auto it = std::find(names.begin(), names.end(), name);
  if (it == names.end()) return std::nullopt;
  return static_cast<int>(it - names.begin());
}

}  // namespace

Eigen::VectorXf MorphableModel::shape(const Eigen::VectorXf& alpha) const {
  return mean + basis * stddev.cwiseProduct(alpha);
}

Mesh MorphableModel::mesh(const Eigen::VectorXf& shape_vector) const {
  Mesh m;
  m.vertices = Eigen::Map<const Eigen::Matrix3Xf>(shape_vector.data(), 3, num_vertices());
  m.triangles = triangles;
  return m;
}

std::optional<int> MorphableModel::pose_index(std::string_view name) const { return index_of(pose_names, name); }

std::optional<int> MorphableModel::expression_index(std::string_view name) const {
  return index_of(expression_names, name);
}

int MorphableModel::mapped_landmark_count() const {
  return static_cast<int>(
      std::count_if(landmark_vertex.begin(), landmark_vertex.end(), [](std::int32_t v) { return v >= 0; }));
}

}  // namespace lipdrive
