// A 3D morphable model (docs/method.md 2): S = mean + basis * (stddev .* alpha), plus, for a
// model with expression shapes (the ICT head), S = mean + basis * (stddev .* alpha) + expressions * w.
#pragma once

#include "core/landmarks.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

using Triangle = std::array<std::uint32_t, 3>;

/// A triangle mesh in model space: millimetres, x towards the subject's left
/// (image right when the face looks at the camera), y up, z out of the face.
struct Mesh {
  Eigen::Matrix3Xf vertices;  // column i = vertex i
  std::vector<Triangle> triangles;
};

struct MorphableModel {
  Eigen::VectorXf mean;      // 3N: x1,y1,z1,...,xN,yN,zN
  Eigen::VectorXf stddev;    // K: standard deviation of each component (sqrt eigenvalue)
  Eigen::MatrixXf basis;     // 3N x K, orthonormal columns, descending variance
  float total_variance = 0;  // variance of the training poses, including dropped components
  std::vector<Triangle> triangles;
  std::array<std::int32_t, kNumLandmarks> landmark_vertex{};  // iBUG index -> vertex, -1 = unmapped
  std::vector<std::string> pose_names;                        // the example poses the model was built from
  Eigen::MatrixXf pose_coefficients;                          // K x P: column p = alpha of pose p
  // An identity + expression model (docs/method.md 2): the components above are the identity
  // (alpha, frozen per performer) and these the expression shapes (weights w in [0, 1]).
  Eigen::MatrixXf expressions;                // 3N x E: column e = displacement of shape e at weight 1 (mm)
  std::vector<std::string> expression_names;  // E names (ARKit-style, as the source model spells them)

  int num_vertices() const { return static_cast<int>(mean.size() / 3); }
  int num_components() const { return static_cast<int>(stddev.size()); }
  int num_poses() const { return static_cast<int>(pose_names.size()); }
  int num_expressions() const { return static_cast<int>(expression_names.size()); }
  bool has_expressions() const { return !expression_names.empty(); }

  /// Shape vector for coefficients alpha (in units of each component's stddev).
  Eigen::VectorXf shape(const Eigen::VectorXf& alpha) const;
  /// Shape vector of a model with expression shapes: identity alpha plus expression weights w.
  Eigen::VectorXf shape(const Eigen::VectorXf& alpha, const Eigen::VectorXf& w) const;
  /// The mesh of a shape vector.
  Mesh mesh(const Eigen::VectorXf& shape_vector) const;
  std::optional<int> pose_index(std::string_view name) const;
  std::optional<int> expression_index(std::string_view name) const;
  int mapped_landmark_count() const;
};

/// The model on the vertices its landmarks map to, in vertex order, with landmark_vertex
/// renumbered and no triangles: everything fitting, the identity, the rest point and the mouth
/// measures read of it (they read a model at its landmark vertices only), for a fraction of the
/// memory (the ICT head: 6,706 vertices -> 68).
MorphableModel landmark_vertices_only(const MorphableModel& model);

}  // namespace lipdrive
