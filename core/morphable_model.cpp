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

Eigen::VectorXf MorphableModel::shape(const Eigen::VectorXf& alpha, const Eigen::VectorXf& w) const {
  return shape(alpha) + expressions * w;
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

MorphableModel landmark_vertices_only(const MorphableModel& model) {
  std::vector<std::int32_t> kept;
  for (const std::int32_t v : model.landmark_vertex)
    if (v >= 0) kept.push_back(v);
  std::sort(kept.begin(), kept.end());
  kept.erase(std::unique(kept.begin(), kept.end()), kept.end());
  const auto rows = static_cast<Eigen::Index>(3 * kept.size());
  // Field by field: a copy of the whole model would double the memory this saves, if briefly.
  MorphableModel out;
  out.stddev = model.stddev;
  out.total_variance = model.total_variance;
  out.landmark_vertex = model.landmark_vertex;
  out.pose_names = model.pose_names;
  out.pose_coefficients = model.pose_coefficients;
  out.expression_names = model.expression_names;
  out.mean.resize(rows);
  out.basis.resize(rows, model.basis.cols());
  out.expressions.resize(rows, model.expressions.cols());
  for (std::size_t k = 0; k < kept.size(); ++k)
    for (int axis = 0; axis < 3; ++axis) {
      const auto from = 3 * static_cast<Eigen::Index>(kept[k]) + axis, to = 3 * static_cast<Eigen::Index>(k) + axis;
      out.mean(to) = model.mean(from);
      out.basis.row(to) = model.basis.row(from);
      if (model.expressions.size() > 0) out.expressions.row(to) = model.expressions.row(from);
    }
  for (std::int32_t& v : out.landmark_vertex)
    if (v >= 0) v = static_cast<std::int32_t>(std::lower_bound(kept.begin(), kept.end(), v) - kept.begin());
  return out;
}

}  // namespace lipdrive
