// The moments behind the per-frame fits (core/fitting.cpp, core/expression_fitting.cpp):
// the affine camera by the Gold Standard algorithm and the normal equations of a linear
// shape, both from sums over the landmarks. Internal to core's fitters.
#pragma once

#include "core/landmarks.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <array>
#include <cmath>
#include <limits>

// Both least-squares problems of docs/method.md 3 are solved through their normal equations,
// and those only need sums over the landmarks (moments). The sums that involve the model
// are quadratic in alpha with coefficients that do not change per frame, so they are
// precomputed; the sums that involve the detected landmarks are formed once per frame.
// An iteration then costs O(K^2) whatever the landmark count.
//
// Notation: set landmark i has mean position m_i, centred m'_i = m_i - m̄, basis rows V̂_i
// (3 x K, scaled by stddev), detected position y_i, centred y'_i = y_i - c2. B_a is the
// L x K matrix of the a-th rows (a = x, y, z) of all V̂_i.

namespace lipdrive::fit_detail {

template <int Rows, int Cols>
using Mat = Eigen::Matrix<double, Rows, Cols>;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// The frame-independent moments of the set's landmarks of the model.
template <int K>
struct ModelMoments {
  Mat<3, 1> centroid;             // m̄
  Mat<3, 3> scatter;              // sum_i m'_i m'_i^T
  Mat<K, 9> basis_mean;           // column 3a + b: B_a^T m'_(b) = sum_i V̂_i[a,:]^T m'_i[b]
  Mat<K, 3> basis_sum;            // column a: B_a^T 1
  std::array<Mat<K, K>, 6> gram;  // G_xx, G_yy, G_zz, G_xy + G_yx, G_xz + G_zx, G_yz + G_zy
};

/// The moments of one frame's detected landmarks of the set.
template <int K>
struct ImageMoments {
  Mat<2, 1> centroid;          // c2
  double mean_squared_radius;  // (1/L) sum_i |y'_i|^2
  Mat<3, 2> mean_cross;        // sum_i m'_i y'_i^T
  Mat<K, 6> basis_cross;       // column 2a + c: B_a^T y'_(c)
};

/// The moments of the model's landmarks X_i = m_i + V̂_i alpha, against the frame's.
struct ShapeMoments {
  Mat<3, 1> centroid;  // c3
  Mat<3, 3> scatter;   // sum_i (X_i - c3)(X_i - c3)^T
  Mat<3, 2> cross;     // sum_i (X_i - c3) y'_i^T
};

/// G_ab = B_a^T B_b, the blocks of A^T A and of the landmarks' scatter (see shape_normal_matrix).
/// G_ba = G_ab^T, and both uses weigh G_ab and G_ba equally, so each off-diagonal pair is stored summed.
template <int L, int K>
std::array<Mat<K, K>, 6> landmark_gram(const Mat<3 * L, K>& basis) {
  const auto rows = [&](int axis) { return basis.template middleRows<L>(axis * L); };
  const auto gram = [&](int a, int b) -> Mat<K, K> { return rows(a).transpose() * rows(b); };
  const Mat<K, K> xy = gram(0, 1), xz = gram(0, 2), yz = gram(1, 2);
  return {gram(0, 0), gram(1, 1), gram(2, 2), xy + xy.transpose(), xz + xz.transpose(), yz + yz.transpose()};
}

/// `basis` holds the V̂_i as [B_x; B_y; B_z], `mean` the m_i as rows.
template <int L, int K>
ModelMoments<K> model_moments(const Mat<3 * L, K>& basis, const Mat<L, 3>& mean) {
  ModelMoments<K> moments;
  moments.centroid = mean.colwise().mean().transpose();
  const Mat<L, 3> centred = mean.rowwise() - moments.centroid.transpose();
  moments.scatter = centred.transpose() * centred;
  for (int a = 0; a < 3; ++a) {
    const auto rows = basis.template middleRows<L>(a * L);
    moments.basis_mean.template middleCols<3>(3 * a) = rows.transpose() * centred;
    moments.basis_sum.col(a) = rows.transpose() * Mat<L, 1>::Ones();
  }
  moments.gram = landmark_gram<L, K>(basis);
  return moments;
}

template <int L, int K>
ImageMoments<K> image_moments(const Mat<3 * L, K>& basis, const Mat<L, 3>& centred_mean,
                              const Mat<L, 2>& image_points) {
  ImageMoments<K> moments;
  moments.centroid = image_points.colwise().mean().transpose();
  const Mat<L, 2> centred = image_points.rowwise() - moments.centroid.transpose();
  moments.mean_squared_radius = centred.squaredNorm() / L;
  moments.mean_cross.noalias() = centred_mean.transpose().lazyProduct(centred);
  // As (y'^T B_a)^T: every coefficient is then a dot product of two contiguous columns.
  for (int a = 0; a < 3; ++a)
    moments.basis_cross.template middleCols<2>(2 * a).transpose().noalias() =
        centred.transpose().lazyProduct(basis.template middleRows<L>(a * L));
  return moments;
}

/// Expands sum_i X_i X_i^T and sum_i X_i y'_i^T for X_i = m_i + V̂_i alpha (docs/method.md 2):
/// constant, linear and quadratic terms in alpha, all from precomputed moments.
template <int L, int K>
ShapeMoments shape_moments(const ModelMoments<K>& model, const ImageMoments<K>& image, const Mat<K, 1>& alpha) {
  // lazyProduct: at these sizes Eigen's general matrix-vector kernel costs more than the arithmetic.
  const Mat<3, 1> offset = model.basis_sum.transpose().lazyProduct(alpha) / L;  // mean of V̂_i alpha
  const Mat<9, 1> linear = model.basis_mean.transpose().lazyProduct(alpha);     // sum_i m'_i (V̂_i alpha)^T
  const Mat<6, 1> cross = image.basis_cross.transpose().lazyProduct(alpha);     // sum_i (V̂_i alpha) y'_i^T
  // sum_i (V̂_i alpha)_a (V̂_i alpha)_b = alpha^T G_ab alpha: the six G_ab alpha in one pass over
  // the columns (each column a multiple of alpha_j added), then six dot products.
  Mat<K, 6> products = Mat<K, 6>::Zero();
  for (int j = 0; j < K; ++j)
    for (int block = 0; block < 6; ++block) products.col(block) += alpha[j] * model.gram[block].col(j);
  const Mat<6, 1> forms = products.transpose().lazyProduct(alpha);
  Mat<3, 3> quadratic;
  for (int a = 0; a < 3; ++a) quadratic(a, a) = forms[a];
  quadratic(0, 1) = quadratic(1, 0) = 0.5 * forms[3];
  quadratic(0, 2) = quadratic(2, 0) = 0.5 * forms[4];
  quadratic(1, 2) = quadratic(2, 1) = 0.5 * forms[5];

  const Eigen::Map<const Mat<3, 3>> linear_matrix(linear.data());
  ShapeMoments moments;
  moments.centroid = model.centroid + offset;
  moments.scatter = model.scatter + linear_matrix + linear_matrix.transpose() + quadratic -
                    static_cast<double>(L) * offset * offset.transpose();
  moments.cross = image.mean_cross + Eigen::Map<const Mat<2, 3>>(cross.data()).transpose();
  return moments;
}

/// A similarity x -> scale * (x - centroid) as a homogeneous (D+1)x(D+1) matrix [sI, -s c; 0 1].
template <int D>
Mat<D + 1, D + 1> similarity(const Mat<D, 1>& centroid, double scale) {
  Mat<D + 1, D + 1> matrix = Mat<D + 1, D + 1>::Identity();
  matrix.template topLeftCorner<D, D>() *= scale;
  matrix.template topRightCorner<D, 1>() = -scale * centroid;
  return matrix;
}

/// Its inverse, [I/s, c; 0 1].
template <int D>
Mat<D + 1, D + 1> similarity_inverse(const Mat<D, 1>& centroid, double scale) {
  Mat<D + 1, D + 1> matrix = Mat<D + 1, D + 1>::Identity();
  matrix.template topLeftCorner<D, D>() /= scale;
  matrix.template topRightCorner<D, 1>() = centroid;
  return matrix;
}

/// Affine camera by the Gold Standard algorithm (Hartley & Zisserman, Multiple View Geometry,
/// 2nd ed., Alg. 7.2): normalise x~ = T x (centroid to origin, RMS distance sqrt 2) and X~ = U X
/// (RMS distance sqrt 3); solve the 2L x 8 least-squares system [X~^T 0; 0 X~^T][c~1; c~2] = [x~; y~],
/// which decouples into two L x 4 problems with the normal matrix X~^T X~; third row of C~ is
/// [0 0 0 1]; C = T^-1 C~ U. With X~_i = [s3 (X_i - c3); 1] and x~_i = s2 y'_i, the normal
/// equations are X~^T X~ = [s3^2 scatter, 0; 0, L] and X~^T [x~ y~] = [s3 s2 cross; 0 0].
template <int L>
Mat<3, 4> estimate_affine_camera(const ShapeMoments& shape, const Mat<2, 1>& image_centroid,
                                 double image_mean_squared_radius) {
  const double image_scale = std::sqrt(2.0 / image_mean_squared_radius);
  const double model_scale = std::sqrt(3.0 * L / shape.scatter.trace());
  Mat<4, 4> normal_matrix = Mat<4, 4>::Zero();
  normal_matrix.topLeftCorner<3, 3>() = model_scale * model_scale * shape.scatter;
  normal_matrix(3, 3) = L;
  Mat<4, 2> normal_rhs = Mat<4, 2>::Zero();
  normal_rhs.topRows<3>() = model_scale * image_scale * shape.cross;
  const Mat<4, 2> rows = Eigen::LLT<Mat<4, 4>>(normal_matrix).solve(normal_rhs);  // columns c~1, c~2

  Mat<3, 4> normalised_camera = Mat<3, 4>::Zero();
  normalised_camera.topRows<2>() = rows.transpose();
  normalised_camera(2, 3) = 1.0;
  return similarity_inverse<2>(image_centroid, image_scale) * normalised_camera *
         similarity<3>(shape.centroid, model_scale);
}

/// A^T A of the shape fit, A stacking A_i = R V̂_i (R the 2x3 part of the camera): with
/// M = R^T R, A^T A = sum_i V̂_i^T M V̂_i = sum_ab M_ab G_ab.
template <int K>
Mat<K, K> shape_normal_matrix(const ModelMoments<K>& model, const Mat<3, 4>& camera) {
  const Mat<2, 3> R = camera.template topLeftCorner<2, 3>();
  Mat<3, 3> M;
  M.noalias() = R.transpose() * R;
  const auto& G = model.gram;
  return M(0, 0) * G[0] + M(1, 1) * G[1] + M(2, 2) * G[2] + M(0, 1) * G[3] + M(0, 2) * G[4] + M(1, 2) * G[5];
}

/// A^T b of the shape fit, b_i = R m_i + t - y_i the mean shape's reprojection residual (eos,
/// fit_shape_to_landmarks_linear). With b_i = R m'_i - y'_i + e, e = R m̄ + t - c2:
/// A^T b = sum_i V̂_i^T R^T b_i = sum_ab M_ab B_a^T m'_(b) - sum_ac R_ca B_a^T y'_(c) + sum_a (R^T e)_a B_a^T 1.
template <int K>
Mat<K, 1> shape_rhs(const ModelMoments<K>& model, const ImageMoments<K>& image, const Mat<3, 4>& camera) {
  const Mat<2, 3> R = camera.template topLeftCorner<2, 3>();
  Mat<3, 3> M;
  M.noalias() = R.transpose() * R;
  const Mat<2, 1> e = R * model.centroid + camera.template topRightCorner<2, 1>() - image.centroid;
  Mat<K, 1> rhs;
  rhs.noalias() = model.basis_mean.lazyProduct(M.reshaped());    // column 3a + b meets M(b, a) = M(a, b)
  rhs.noalias() -= image.basis_cross.lazyProduct(R.reshaped());  // column 2a + c meets R(c, a)
  rhs.noalias() += model.basis_sum.lazyProduct(R.transpose() * e);
  return rhs;
}

}  // namespace lipdrive::fit_detail
