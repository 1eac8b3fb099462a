#include "core/model_builder.hpp"

#include "core/model_format.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>

namespace lipdrive {
namespace {

void validate(const ModelBuildInput& input, const ModelBuildOptions& options) {
  if (input.pose_names.size() != input.pose_vertices.size())
    throw ModelBuildError("pose_names and pose_vertices differ in length");
  if (input.pose_vertices.size() < 2)
    throw ModelBuildError("a model needs at least 2 poses, got " + std::to_string(input.pose_vertices.size()));
  const Eigen::Index n = input.pose_vertices.front().cols();
  if (n == 0) throw ModelBuildError("pose '" + input.pose_names.front() + "' has no vertices");
  for (std::size_t p = 0; p < input.pose_vertices.size(); ++p) {
    const auto& vertices = input.pose_vertices[p];
    if (vertices.cols() != n)
      throw ModelBuildError("pose '" + input.pose_names[p] + "' has " + std::to_string(vertices.cols()) +
                            " vertices, pose '" + input.pose_names.front() + "' has " + std::to_string(n));
    if (!vertices.allFinite())
      throw ModelBuildError("pose '" + input.pose_names[p] + "' has a non-finite vertex coordinate");
  }
  for (std::size_t t = 0; t < input.triangles.size(); ++t)
    for (std::uint32_t v : input.triangles[t])
      if (v >= static_cast<std::uint64_t>(n))
        throw ModelBuildError("triangle " + std::to_string(t) + " refers to vertex " + std::to_string(v) + " of " +
                              std::to_string(n));
  for (int l = 0; l < kNumLandmarks; ++l) {
    const std::int32_t v = input.landmark_vertex[l];
    if (v < -1 || v >= n)
      throw ModelBuildError("landmark " + std::to_string(l) + " maps to vertex " + std::to_string(v) + ", outside 0.." +
                            std::to_string(n - 1) + " (or -1 for unmapped)");
  }
  if (options.components < 0) throw ModelBuildError("component count must be >= 0 (0 = by variance target)");
  if (!(options.variance_target > 0 && options.variance_target <= 1))
    throw ModelBuildError("variance target must be in (0, 1], got " + std::to_string(options.variance_target));
}

// Number of components to keep: the requested count, or the smallest K whose
// cumulative variance reaches the target; never more than the non-zero ones.
Eigen::Index choose_components(const Eigen::VectorXd& eigenvalues, Eigen::Index nonzero,
                               const ModelBuildOptions& options) {
  if (options.components > 0) return std::min<Eigen::Index>(options.components, nonzero);
  const double goal = options.variance_target * eigenvalues.sum();
  double cumulative = 0;
  for (Eigen::Index k = 0; k < nonzero; ++k) {
    cumulative += eigenvalues[k];
    if (cumulative >= goal) return k + 1;
  }
  return nonzero;
}

}  // namespace

MorphableModel build_model(const ModelBuildInput& input, const ModelBuildOptions& options) {
  validate(input, options);
  const auto poses = static_cast<Eigen::Index>(input.pose_vertices.size());
  const Eigen::Index dims = 3 * input.pose_vertices.front().cols();

  // Row p = shape vector of pose p; double precision so that small components survive.
  Eigen::MatrixXd data(poses, dims);
  for (Eigen::Index p = 0; p < poses; ++p)
    data.row(p) = Eigen::Map<const Eigen::VectorXf>(input.pose_vertices[p].data(), dims).cast<double>();
  const Eigen::RowVectorXd mean = data.colwise().mean();
  data.rowwise() -= mean;

  const Eigen::BDCSVD<Eigen::MatrixXd> svd(data, Eigen::ComputeThinV);
  const Eigen::VectorXd eigenvalues = svd.singularValues().array().square() / double(poses - 1);
  // Components below this share of the largest are rounding noise of a rank-deficient set.
  const double noise_floor = 1e-12 * eigenvalues[0];
  const auto nonzero = static_cast<Eigen::Index>((eigenvalues.array() > noise_floor).count());
  if (nonzero == 0) throw ModelBuildError("all poses are identical: there is no variation to model");
  const Eigen::Index k = choose_components(eigenvalues, nonzero, options);

  Eigen::MatrixXd basis = svd.matrixV().leftCols(k);
  // SVD signs are arbitrary; make the largest entry of each component positive
  // so the same poses give the same model on every machine.
  for (Eigen::Index c = 0; c < k; ++c) {
    Eigen::Index largest = 0;
    basis.col(c).cwiseAbs().maxCoeff(&largest);
    if (basis(largest, c) < 0) basis.col(c) *= -1;
  }
  const Eigen::VectorXd stddev = eigenvalues.head(k).cwiseSqrt();

  MorphableModel model;
  model.mean = mean.transpose().cast<float>();
  model.stddev = stddev.cast<float>();
  model.basis = basis.cast<float>();
  model.total_variance = static_cast<float>(eigenvalues.sum());
  model.triangles = input.triangles;
  model.landmark_vertex = input.landmark_vertex;
  model.pose_names = input.pose_names;
  model.pose_coefficients = (stddev.cwiseInverse().asDiagonal() * (basis.transpose() * data.transpose())).cast<float>();
  // The file holds 32-bit floats: coordinates beyond about 1e19 units (or differing by less
  // than 1e-19) make a model the loader refuses; the loader's own checks say so here.
  try {
    validate_model_values(model, "the model built");
  } catch (const ModelFormatError& e) {
    throw ModelBuildError(std::string(e.what()) + ": scale the poses' coordinates to millimetres or metres");
  }
  return model;
}

}  // namespace lipdrive
