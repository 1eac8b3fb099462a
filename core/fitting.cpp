#include "core/fitting.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>

// Both least-squares problems of docs/method.md 3 are solved through their normal equations,
// and those only need sums over the landmarks (moments). The sums that involve the model
// are quadratic in alpha with coefficients that do not change per frame, so they are
// precomputed; the sums that involve the detected landmarks are formed once per frame.
// An iteration then costs O(K^2) whatever the landmark count.
//
// Notation: set landmark i has mean position m_i, centred m'_i = m_i - m̄, basis rows V̂_i
// (3 x K, scaled by stddev), detected position y_i, centred y'_i = y_i - c2. B_a is the
// L x K matrix of the a-th rows (a = x, y, z) of all V̂_i.

namespace lipdrive {
namespace {

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
  // sum_i (V̂_i alpha)_a (V̂_i alpha)_b = alpha^T G_ab alpha, each as one pass over G_ab.
  const Mat<K, K> outer = alpha.lazyProduct(alpha.transpose());
  const auto form = [&](int block) { return model.gram[block].cwiseProduct(outer).sum(); };
  Mat<3, 3> quadratic;
  for (int a = 0; a < 3; ++a) quadratic(a, a) = form(a);
  quadratic(0, 1) = quadratic(1, 0) = 0.5 * form(3);
  quadratic(0, 2) = quadratic(2, 0) = 0.5 * form(4);
  quadratic(1, 2) = quadratic(2, 1) = 0.5 * form(5);

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

/// Regularised linear shape fit (Huber et al., "A Multiresolution 3D Morphable Face Model and
/// Fitting Framework", VISAPP 2016; eos fit_shape_to_landmarks_linear): minimises
/// sum_i ||y_proj,i - y_2D,i||^2 / (2 sigma^2) + lambda ||alpha||^2 in closed form,
/// (A^T Omega A + lambda I) alpha = -A^T Omega b with Omega = I / sigma^2, by Cholesky (LLT).
template <int K>
Mat<K, 1> solve_shape(const Mat<K, K>& AtA, const Mat<K, 1>& Atb, double sigma_px, double lambda) {
  const double omega = 1.0 / (sigma_px * sigma_px);
  Mat<K, K> lhs = omega * AtA;
  lhs.diagonal().array() += lambda;
  return Eigen::LLT<Mat<K, K>>(lhs).solve(-omega * Atb);
}

/// V̂ rows of one vertex (3 x K, zero beyond the model's components): basis scaled by stddev.
template <int K>
Mat<3, K> scaled_basis_rows(const MorphableModel& model, int vertex, int num_components) {
  Mat<3, K> rows = Mat<3, K>::Zero();
  rows.leftCols(num_components) =
      (model.basis.block(3 * vertex, 0, 3, num_components) * model.stddev.head(num_components).asDiagonal())
          .template cast<double>();
  return rows;
}

template <int L, int K>
class FixedSizeFitter final : public FitterBase {
 public:
  FixedSizeFitter(const MorphableModel& model, std::span<const int> set_indices, int num_components,
                  FitSettings settings)
      : settings_(settings) {
    std::copy(set_indices.begin(), set_indices.end(), indices_.begin());
    Mat<L, 3> mean;
    for (int i = 0; i < L; ++i) {
      const int vertex = model.landmark_vertex[indices_[i]];
      mean.row(i) = model.mean.segment<3>(3 * vertex).template cast<double>().transpose();
      const Mat<3, K> rows = scaled_basis_rows<K>(model, vertex, num_components);
      for (int axis = 0; axis < 3; ++axis) basis_.row(axis * L + i) = rows.row(axis);
    }
    moments_ = model_moments<L, K>(basis_, mean);
    centred_mean_ = mean.rowwise() - moments_.centroid.transpose();

    all_mean_.setConstant(kNaN);
    all_basis_.setZero();
    for (int landmark = 0; landmark < kNumLandmarks; ++landmark) {
      const int vertex = model.landmark_vertex[landmark];
      if (vertex < 0) continue;
      all_mean_.col(landmark) = model.mean.segment<3>(3 * vertex).template cast<double>();
      all_basis_.template middleRows<3>(3 * landmark) = scaled_basis_rows<K>(model, vertex, num_components);
    }
  }

  void fit(const Landmarks2D& detected, FitOutput& inout) const override {
    Mat<L, 2> image_points;
    for (int i = 0; i < L; ++i) image_points.row(i) = detected.col(indices_[i]).transpose();
    const ImageMoments<K> image = image_moments<L, K>(basis_, centred_mean_, image_points);

    Mat<K, 1> alpha = inout.coefficients.template head<K>();
    Mat<3, 4> camera = Mat<3, 4>::Zero();  // set by the first iteration (iterations >= 1)
    for (int iteration = 0; iteration < settings_.iterations; ++iteration) {
      camera = estimate_affine_camera<L>(shape_moments<L, K>(moments_, image, alpha), image.centroid,
                                         image.mean_squared_radius);
      alpha = solve_shape<K>(shape_normal_matrix<K>(moments_, camera), shape_rhs<K>(moments_, image, camera),
                             settings_.sigma_px, settings_.lambda);
    }
    write_output(camera, alpha, image_points, inout);
  }

 private:
  void write_output(const Mat<3, 4>& camera, const Mat<K, 1>& alpha, const Mat<L, 2>& image_points,
                    FitOutput& out) const {
    out.camera = camera;
    out.coefficients.setZero();
    out.coefficients.template head<K>() = alpha;
    Eigen::Map<Mat<3 * kNumLandmarks, 1>>(out.model_landmarks.data()).noalias() = all_basis_.lazyProduct(alpha);
    out.model_landmarks += all_mean_;
    out.projected.noalias() = camera.template topLeftCorner<2, 3>().lazyProduct(out.model_landmarks);
    out.projected.colwise() += camera.template topRightCorner<2, 1>();
    double squared_error = 0;
    for (int i = 0; i < L; ++i)
      squared_error += (out.projected.col(indices_[i]) - image_points.row(i).transpose()).squaredNorm();
    out.reprojection_error_px = std::sqrt(squared_error / L);
  }

  FitSettings settings_;
  std::array<int, L> indices_;  // iBUG index of each set landmark
  Mat<3 * L, K> basis_;         // V̂ at the set's landmarks: [B_x; B_y; B_z]
  Mat<L, 3> centred_mean_;      // m'_i, one per row (mm)
  ModelMoments<K> moments_;
  Mat<3, kNumLandmarks> all_mean_;       // m at all 68 landmarks, NaN where unmapped
  Mat<3 * kNumLandmarks, K> all_basis_;  // V̂ at all 68 landmarks, rows x, y, z per landmark
};

template <int K, LandmarkSet S>
std::unique_ptr<FitterBase> fitter_for(const MorphableModel& model, int num_components, FitSettings settings) {
  return std::make_unique<FixedSizeFitter<landmark_count(S), K>>(model, landmark_indices(S), num_components, settings);
}

template <int K>
std::unique_ptr<FitterBase> make_fixed_size_fitter(const MorphableModel& model, LandmarkSet set, int num_components,
                                                   FitSettings settings) {
  switch (set) {
    case LandmarkSet::F1: return fitter_for<K, LandmarkSet::F1>(model, num_components, settings);
    case LandmarkSet::F2: return fitter_for<K, LandmarkSet::F2>(model, num_components, settings);
    case LandmarkSet::F3: return fitter_for<K, LandmarkSet::F3>(model, num_components, settings);
    case LandmarkSet::F4: return fitter_for<K, LandmarkSet::F4>(model, num_components, settings);
    case LandmarkSet::F5: return fitter_for<K, LandmarkSet::F5>(model, num_components, settings);
  }
  throw std::invalid_argument("Fitter: unknown landmark set");
}

void check_fit_inputs(const MorphableModel& model, LandmarkSet set, const FitSettings& settings) {
  if (settings.iterations < 1) throw std::invalid_argument("Fitter: iterations must be at least 1");
  if (!(settings.lambda > 0)) throw std::invalid_argument("Fitter: lambda must be positive");
  if (!(settings.sigma_px > 0)) throw std::invalid_argument("Fitter: sigma_px must be positive");
  if (model.num_components() < 1) throw std::invalid_argument("Fitter: the model has no shape components");
  if (model.basis.rows() != model.mean.size() || model.basis.cols() != model.num_components())
    throw std::invalid_argument("Fitter: the model's basis does not match its mean and stddev sizes");
  for (int landmark = 0; landmark < kNumLandmarks; ++landmark) {
    const int vertex = model.landmark_vertex[landmark];
    if (vertex >= model.num_vertices())
      throw std::invalid_argument("Fitter: landmark " + std::to_string(landmark) + " maps to vertex " +
                                  std::to_string(vertex) + " beyond the model's " +
                                  std::to_string(model.num_vertices()) + " vertices");
  }
  for (const int landmark : landmark_indices(set))
    if (model.landmark_vertex[landmark] < 0)
      throw std::invalid_argument("Fitter: landmark " + std::to_string(landmark) + " of set " +
                                  std::string(landmark_set_name(set)) + " is not mapped to a model vertex");
}

}  // namespace

Fitter::Fitter(const MorphableModel& model, LandmarkSet set, FitSettings settings)
    : num_components_(std::min(model.num_components(), kMaxFitComponents)),
      truncated_(model.num_components() > kMaxFitComponents) {
  check_fit_inputs(model, set, settings);
  // Two compiled sizes keep the code small; unused components of the larger size have zero
  // basis columns, so lambda holds them at exactly zero.
  impl_ = num_components_ <= 20 ? make_fixed_size_fitter<20>(model, set, num_components_, settings)
                                : make_fixed_size_fitter<kMaxFitComponents>(model, set, num_components_, settings);
}

void Fitter::fit(const Landmarks2D& detected, FitOutput& inout) const { impl_->fit(detected, inout); }

FitOutput Fitter::initial_output() {
  FitOutput output;
  output.camera.setZero();
  output.camera(2, 3) = 1.0;
  output.coefficients.setZero();
  output.projected.setConstant(kNaN);
  output.model_landmarks.setConstant(kNaN);
  output.reprojection_error_px = kNaN;
  return output;
}

}  // namespace lipdrive
