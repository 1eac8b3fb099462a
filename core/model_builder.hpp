// Builds a morphable model from example meshes by PCA (docs/method.md 2).
#pragma once

#include "core/landmarks.hpp"
#include "core/morphable_model.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace lipdrive {

/// Input the builder cannot use (too few poses, mismatched sizes, ...).
class ModelBuildError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct ModelBuildInput {
  std::vector<std::string> pose_names;
  std::vector<Eigen::Matrix3Xf> pose_vertices;  // same vertex order in every pose
  std::vector<Triangle> triangles;
  std::array<std::int32_t, kNumLandmarks> landmark_vertex;  // -1 = unmapped
};

struct ModelBuildOptions {
  int components = 0;             // 0 = the smallest K whose variance reaches variance_target
  double variance_target = 0.99;  // fraction of the total variance, in (0, 1]
};

/// PCA over the poses: mean of all poses; thin SVD of the centred n x 3N data
/// matrix D = U S Vᵀ; eigenvalues of the sample covariance s²/(n−1); basis = V.
/// K ≤ n−1, ≤ the requested count, and only components with non-zero variance.
/// Each pose's coefficients are basisᵀ(pose − mean) / stddev.
MorphableModel build_model(const ModelBuildInput& input, const ModelBuildOptions& options);

}  // namespace lipdrive
