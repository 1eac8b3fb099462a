// Test fixtures for the fitter: a random face-sized model, synthetic landmarks, and a
// plainly written dynamic-size reference of docs/method.md 3 that builds the full 2L x 8 and
// 2L x K systems literally, to check the fixed-size Fitter against.
#pragma once

#include "core/fitting.hpp"
#include "core/landmarks.hpp"
#include "core/morphable_model.hpp"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <span>
#include <vector>

namespace lipdrive::testing {

/// A model with random geometry: mean ~ a face-sized point cloud (mm), orthonormal random
/// basis (QR of a Gaussian matrix), stddevs decreasing from 8 mm, 68 distinct landmark vertices.
inline MorphableModel random_model(int num_vertices, int num_components, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const auto random_matrix = [&](int rows, int cols) {
    return Eigen::MatrixXd(Eigen::MatrixXd::NullaryExpr(rows, cols, [&] { return gauss(rng); }));
  };
  MorphableModel model;
  Eigen::Matrix3Xd vertices = random_matrix(3, num_vertices);
  vertices.row(0) *= 45.0;  // width
  vertices.row(1) *= 60.0;  // height
  vertices.row(2) *= 20.0;  // depth
  model.mean = Eigen::Map<Eigen::VectorXd>(vertices.data(), 3 * num_vertices).cast<float>();
  const Eigen::MatrixXd q =
      Eigen::HouseholderQR<Eigen::MatrixXd>(random_matrix(3 * num_vertices, num_components)).householderQ() *
      Eigen::MatrixXd::Identity(3 * num_vertices, num_components);
  model.basis = q.cast<float>();
  model.stddev.resize(num_components);
  for (int k = 0; k < num_components; ++k) model.stddev(k) = static_cast<float>(8.0 * std::pow(0.85, k));
  std::vector<int> order(num_vertices);
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  std::copy_n(order.begin(), kNumLandmarks, model.landmark_vertex.begin());
  return model;
}

/// Coefficients drawn from the model's prior, N(0, 1), padded with zeros to kMaxFitComponents.
inline Eigen::Matrix<double, kMaxFitComponents, 1> random_coefficients(int num_components, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Eigen::Matrix<double, kMaxFitComponents, 1> alpha = Eigen::Matrix<double, kMaxFitComponents, 1>::Zero();
  for (int k = 0; k < num_components; ++k) alpha(k) = gauss(rng);
  return alpha;
}

/// A weak-perspective camera looking at the face from slightly off-axis: scale px/mm, a
/// rotation (yaw, pitch, roll), y flipped to image rows, principal point (320, 240).
inline Eigen::Matrix<double, 3, 4> test_camera(double px_per_mm, double yaw = 0.2, double pitch = -0.1,
                                               double roll = 0.05) {
  const Eigen::Matrix3d rotation =
      (Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()))
          .toRotationMatrix();
  Eigen::Matrix<double, 3, 4> camera = Eigen::Matrix<double, 3, 4>::Zero();
  camera.row(0).head<3>() = px_per_mm * rotation.row(0);
  camera.row(1).head<3>() = -px_per_mm * rotation.row(1);
  camera.col(3) << 320.0, 240.0, 1.0;
  return camera;
}

/// The model's 68 landmarks (model space, mm) for coefficients alpha, in double precision.
inline Eigen::Matrix<double, 3, kNumLandmarks> model_landmarks(const MorphableModel& model,
                                                               const Eigen::VectorXd& alpha) {
  const int k = std::min<int>(model.num_components(), static_cast<int>(alpha.size()));
  Eigen::Matrix<double, 3, kNumLandmarks> points;
  for (int i = 0; i < kNumLandmarks; ++i) {
    const int v = model.landmark_vertex[i];
    points.col(i) = model.mean.segment<3>(3 * v).cast<double>() +
                    model.basis.block(3 * v, 0, 3, k).cast<double>() *
                        (model.stddev.head(k).cast<double>().cwiseProduct(alpha.head(k)));
  }
  return points;
}

inline Landmarks2D project(const Eigen::Matrix<double, 3, 4>& camera,
                           const Eigen::Matrix<double, 3, kNumLandmarks>& points) {
  return (camera.topLeftCorner<2, 3>() * points).colwise() + camera.topRightCorner<2, 1>();
}

/// The first num_components components of a model.
inline MorphableModel truncated(MorphableModel model, int num_components) {
  model.stddev = model.stddev.head(num_components).eval();
  model.basis = model.basis.leftCols(num_components).eval();
  if (model.pose_coefficients.size() > 0)
    model.pose_coefficients = model.pose_coefficients.topRows(num_components).eval();
  return model;
}

struct ReferenceFit {
  Eigen::Matrix<double, 3, 4> camera;
  Eigen::VectorXd coefficients;
};

/// Normalising similarity of H&Z Alg. 7.2 for the columns of `points`, as a homogeneous matrix.
inline Eigen::MatrixXd reference_normalisation(const Eigen::MatrixXd& points) {
  const int dim = static_cast<int>(points.rows());
  const Eigen::VectorXd centroid = points.rowwise().mean();
  const double rms = std::sqrt((points.colwise() - centroid).colwise().squaredNorm().mean());
  const double scale = std::sqrt(static_cast<double>(dim)) / rms;
  Eigen::MatrixXd transform = Eigen::MatrixXd::Identity(dim + 1, dim + 1);
  transform.topLeftCorner(dim, dim) *= scale;
  transform.topRightCorner(dim, 1) = -scale * centroid;
  return transform;
}

/// docs/method.md 3 written out with dynamic matrices and general solvers.
inline ReferenceFit reference_fit(const MorphableModel& model, LandmarkSet set, const Landmarks2D& detected,
                                  Eigen::VectorXd alpha, const FitSettings& settings) {
  const std::span<const int> indices = landmark_indices(set);
  const int L = static_cast<int>(indices.size());
  const int K = static_cast<int>(alpha.size());
  Eigen::MatrixXd basis(3 * L, K);  // V̂: rows x, y, z of landmark 0, then landmark 1, ...
  Eigen::VectorXd mean(3 * L);
  Eigen::MatrixXd image(2, L);
  for (int i = 0; i < L; ++i) {
    const int v = model.landmark_vertex[indices[i]];
    mean.segment(3 * i, 3) = model.mean.segment(3 * v, 3).cast<double>();
    basis.middleRows(3 * i, 3) =
        model.basis.block(3 * v, 0, 3, K).cast<double>() * model.stddev.head(K).cast<double>().asDiagonal();
    image.col(i) = detected.col(indices[i]);
  }

  ReferenceFit fit;
  for (int iteration = 0; iteration < settings.iterations; ++iteration) {
    const Eigen::VectorXd shape = mean + basis * alpha;
    const Eigen::MatrixXd points = Eigen::Map<const Eigen::MatrixXd>(shape.data(), 3, L);
    const Eigen::MatrixXd T = reference_normalisation(image);
    const Eigen::MatrixXd U = reference_normalisation(points);
    Eigen::MatrixXd x_h(3, L), X_h(4, L);
    x_h << image, Eigen::RowVectorXd::Ones(L);
    X_h << points, Eigen::RowVectorXd::Ones(L);
    const Eigen::MatrixXd x_n = T * x_h, X_n = U * X_h;
    Eigen::MatrixXd system = Eigen::MatrixXd::Zero(2 * L, 8);
    Eigen::VectorXd targets(2 * L);
    system.topLeftCorner(L, 4) = X_n.transpose();
    system.bottomRightCorner(L, 4) = X_n.transpose();
    targets << x_n.row(0).transpose(), x_n.row(1).transpose();
    const Eigen::VectorXd c = system.colPivHouseholderQr().solve(targets);
    Eigen::MatrixXd normalised_camera(3, 4);
    normalised_camera << c.head(4).transpose(), c.tail(4).transpose(), 0, 0, 0, 1;
    fit.camera = T.inverse() * normalised_camera * U;

    const Eigen::MatrixXd R = fit.camera.topLeftCorner(2, 3);
    const Eigen::VectorXd t = fit.camera.topRightCorner(2, 1);
    Eigen::MatrixXd A(2 * L, K);
    Eigen::VectorXd b(2 * L);
    for (int i = 0; i < L; ++i) {
      A.middleRows(2 * i, 2) = R * basis.middleRows(3 * i, 3);
      b.segment(2 * i, 2) = R * mean.segment(3 * i, 3) + t - image.col(i);
    }
    const Eigen::MatrixXd omega = Eigen::MatrixXd::Identity(2 * L, 2 * L) / (settings.sigma_px * settings.sigma_px);
    const Eigen::MatrixXd lhs = A.transpose() * omega * A + settings.lambda * Eigen::MatrixXd::Identity(K, K);
    alpha = lhs.ldlt().solve(-A.transpose() * omega * b);
  }
  fit.coefficients = alpha;
  return fit;
}

}  // namespace lipdrive::testing
