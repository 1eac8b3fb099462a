#include "core/fitting.hpp"

#include "core/fit_moments.hpp"
#include "core/statistics.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace lipdrive {
namespace {

using namespace fit_detail;

/// Columns per panel of cholesky_in_place, rows per block of its substitutions: 4 divides every
/// compiled size (20, 40, 56).
constexpr int kBlock = 4;

/// One panel of cholesky_in_place: columns First to First + kBlock - 1 factored, then subtracted
/// from the columns after them. Each column is touched from the multiple of 8 at or above the
/// panel's first row down, a part whose length the compiler knows; the rows above the diagonal
/// within it hold partial sums that nothing reads, zeroed once at the end.
template <int K, int First>
void factor_panel(Mat<K, K>& a) {
  constexpr int kAlign = 8;
  constexpr int top = First / kAlign * kAlign;
  for (int k = First; k < First + kBlock; ++k) {
    a.col(k).template segment<K - top>(top) *= 1.0 / std::sqrt(a(k, k));
    for (int j = k + 1; j < First + kBlock; ++j)
      a.col(j).template segment<K - top>(top) -= a(j, k) * a.col(k).template segment<K - top>(top);
  }
  if constexpr (First + kBlock < K) {
    constexpr int below = (First + kBlock) / kAlign * kAlign;
    const Mat<K - below, kBlock> panel = a.template block<K - below, kBlock>(below, First);
    for (int j = First + kBlock; j < K; ++j) {
      Mat<K - below, 1> column = a.col(j).template segment<K - below>(below);
      for (int t = 0; t < kBlock; ++t) column -= panel(j - below, t) * panel.col(t);
      a.col(j).template segment<K - below>(below) = column;
    }
  }
}

template <int K, std::size_t... Panel>
void cholesky_in_place(Mat<K, K>& a, std::index_sequence<Panel...>) {
  (factor_panel<K, static_cast<int>(Panel) * kBlock>(a), ...);
  a.template triangularView<Eigen::StrictlyUpper>().setZero();
}

/// The Cholesky factor L of a symmetric positive definite matrix, A = L L^T, in place: L in the
/// lower triangle, zeros above it; only A's lower triangle is read. The outer-product
/// (right-looking) Cholesky in blocks (Golub & Van Loan, Matrix Computations, 4th ed., section
/// 4.2): each panel of 4 columns is factored, then subtracted from the columns after it, with
/// loops whose sizes the compiler knows. Eigen's LLT cuts a 40 x 40 matrix into blocks of
/// run-time size and takes twice as long (docs/performance.md, "The shape fit's Cholesky").
template <int K>
void cholesky_in_place(Mat<K, K>& a) {
  static_assert(K % kBlock == 0);
  cholesky_in_place<K>(a, std::make_index_sequence<K / kBlock>{});
}

/// Solves L z = b for z, L lower triangular with zeros above the diagonal (cholesky_in_place):
/// forward substitution in blocks of 4 rows (Golub & Van Loan, Matrix Computations, 4th ed.,
/// section 3.1, column-oriented, by blocks): each block by scalar substitution, then its 4 columns
/// taken off the whole right-hand side in one product (the rows above it are no longer read).
/// `inverse_diagonal` holds 1 / L_kk, worked out once for both substitutions, so that no division
/// waits for the substitution before it. Eigen's triangular solves, which run its matrix-vector
/// kernels at run-time sizes, made the fit at 40 components 1.6-1.8 us slower
/// (docs/performance.md, "The shape fit's substitutions").
template <int K>
Mat<K, 1> forward_substitution(const Mat<K, K>& lower, const Mat<K, 1>& inverse_diagonal, Mat<K, 1> b) {
  static_assert(K % kBlock == 0);
  Mat<K, 1> z;
  for (int top = 0; top < K; top += kBlock) {
    Mat<kBlock, 1> block = b.template segment<kBlock>(top);
    for (int c = 0; c < kBlock; ++c) {
      block[c] *= inverse_diagonal[top + c];
      for (int r = c + 1; r < kBlock; ++r) block[r] -= lower(top + r, top + c) * block[c];
    }
    z.template segment<kBlock>(top) = block;
    b.noalias() -= lower.template middleCols<kBlock>(top) * block;
  }
  return z;
}

/// Solves L^T x = z for x, L and inverse_diagonal as in forward_substitution: back substitution
/// in blocks of 4 rows from the bottom (the same section): a block's right-hand side less what
/// the rows solved below it contribute (4 dot products with L's columns, x zero where not yet
/// solved), then the block by scalar substitution.
template <int K>
Mat<K, 1> back_substitution_transposed(const Mat<K, K>& lower, const Mat<K, 1>& inverse_diagonal, const Mat<K, 1>& z) {
  static_assert(K % kBlock == 0);
  Mat<K, 1> x = Mat<K, 1>::Zero();
  for (int top = K - kBlock; top >= 0; top -= kBlock) {
    Mat<kBlock, 1> block = z.template segment<kBlock>(top) - lower.template middleCols<kBlock>(top).transpose() * x;
    for (int c = kBlock - 1; c >= 0; --c) {
      x[top + c] = block[c] * inverse_diagonal[top + c];
      for (int r = 0; r < c; ++r) block[r] -= lower(top + c, top + r) * x[top + c];
    }
  }
  return x;
}

/// Regularised linear shape fit (Huber et al., "A Multiresolution 3D Morphable Face Model and
/// Fitting Framework", VISAPP 2016; eos fit_shape_to_landmarks_linear): minimises
/// sum_i ||y_proj,i - y_2D,i||^2 / (2 sigma^2) + lambda ||alpha||^2 in closed form,
/// (A^T Omega A + lambda I) alpha = -A^T Omega b with Omega = I / sigma^2, by Cholesky.
template <int K>
Mat<K, 1> solve_shape(const Mat<K, K>& AtA, const Mat<K, 1>& Atb, double sigma_px, double lambda) {
  const double omega = 1.0 / (sigma_px * sigma_px);
  Mat<K, K> factor = omega * AtA;
  factor.diagonal().array() += lambda;
  cholesky_in_place<K>(factor);
  const Mat<K, 1> inverse_diagonal = factor.diagonal().cwiseInverse();
  return back_substitution_transposed<K>(factor, inverse_diagonal,
                                         forward_substitution<K>(factor, inverse_diagonal, -omega * Atb));
}

/// The camera's scale s (pixels per mm): the RMS norm of the rows of its 2x3 part.
double camera_scale_squared(const Mat<3, 4>& camera) {
  return 0.5 * camera.template topLeftCorner<2, 3>().squaredNorm();
}

/// Expression weights by box-constrained least squares (docs/method.md 3, expression models):
/// minimises 1/2 ||A w + b||^2 / (s^2 sigma^2) + 1/2 sum_e lambda_e w_e^2 + sum_e mu_e w_e over
/// 0 <= w_e <= 1 (the residual over the camera scale s, so in mm on the face whatever the image
/// size; mu the sparse prior, an L1 norm that is linear on w >= 0: Bouaziz, Wang & Pauly, "Online
/// Modeling for Realtime Facial Animation", SIGGRAPH 2013), i.e. 1/2 w^T H w - g^T w with
/// H = A^T A / (s^2 sigma^2) + diag(lambda), g = -A^T b / (s^2 sigma^2) - mu.
/// Cyclic coordinate descent with each coordinate clamped to its bounds (Franc, Hlavac & Navara,
/// "Sequential Coordinate-Wise Algorithm for the Non-negative Least Squares Problem", CAIP 2005,
/// here with an upper bound too): each step sets w_e to the minimiser along e, so the cost never
/// rises; a fixed number of sweeps, warm-started from the last frame. A coordinate with a
/// partner shares the bound w_e + w_partner <= 1 (jawOpen and mouthClose, see ExpressionBasis).
template <int K>
void solve_bounded(const Mat<K, K>& H, const Mat<K, 1>& g, const std::array<int, K>& partner, int sweeps,
                   Mat<K, 1>& w) {
  Mat<K, 1> gradient = H * w - g;  // of 1/2 w^T H w - g^T w
  const Mat<K, 1> inverse_diagonal = H.diagonal().cwiseInverse();  // no division in the chain of steps
  for (int sweep = 0; sweep < sweeps; ++sweep)
    for (int e = 0; e < K; ++e) {
      const double upper = partner[e] < 0 ? 1.0 : 1.0 - w[partner[e]];
      const double next = std::clamp(w[e] - gradient[e] * inverse_diagonal[e], 0.0, std::max(upper, 0.0));
      const double step = next - w[e];
      if (step == 0.0) continue;
      w[e] = next;
      gradient.noalias() += step * H.col(e);
    }
}

/// The shape the per-frame fit moves, at the 68 landmarks: S = mean + basis c, c the
/// coefficients (alpha for a pose-PCA model, the expression weights for an expression model).
template <int K>
struct LandmarkShape {
  Mat<3, kNumLandmarks> mean;              // mm, NaN where unmapped
  Mat<3 * kNumLandmarks, K> basis;         // rows x, y, z per landmark; zero where unmapped or beyond the model
  Mat<K, 1> ridge = Mat<K, 1>::Zero();     // lambda_e of solve_bounded (expression models)
  Mat<K, 1> sparsity = Mat<K, 1>::Zero();  // mu_e of solve_bounded (expression models)
  std::array<int, K> partner;              // bound partner of solve_bounded, -1 = none
  int coefficients = 0;                    // columns in use
  bool expressions = false;                // bounded expression weights, else ridge-regularised alpha
  int jaw_open = -1, mouth_close = -1;     // expression models: the pair fitted as (u, v) (ExpressionBasis)
};

/// V̂ rows of one vertex (3 x K, zero beyond the model's components): basis scaled by stddev.
template <int K>
Mat<3, K> scaled_basis_rows(const MorphableModel& model, int vertex, int num_components) {
  Mat<3, K> rows = Mat<3, K>::Zero();
  rows.leftCols(num_components) =
      (model.basis.block(3 * vertex, 0, 3, num_components) * model.stddev.head(num_components).asDiagonal())
          .template cast<double>();
  return rows;
}

/// A pose-PCA model (or an expression model's identity): mean + V̂ alpha.
template <int K>
LandmarkShape<K> pca_shape(const MorphableModel& model, int num_components) {
  LandmarkShape<K> shape;
  shape.mean.setConstant(kNaN);
  shape.basis.setZero();
  shape.partner.fill(-1);
  shape.coefficients = num_components;
  for (int landmark = 0; landmark < kNumLandmarks; ++landmark) {
    const int vertex = model.landmark_vertex[landmark];
    if (vertex < 0) continue;
    shape.mean.col(landmark) = model.mean.segment<3>(3 * vertex).template cast<double>();
    shape.basis.template middleRows<3>(3 * landmark) = scaled_basis_rows<K>(model, vertex, num_components);
  }
  return shape;
}

/// An expression model with a frozen identity: mean + V̂ alpha + E w, w in [0, 1]. Shapes the
/// landmarks cannot show (is_unobservable_expression) keep a zero column, so they stay at 0.
/// jawOpen j and mouthClose c are fitted as u = j - c and v = c, the columns E_jaw and
/// E_jaw + E_close, both >= 0 with u + v <= 1: ARKit's mouthClose closes the lips against an
/// open jaw, so c <= j.
template <int K>
LandmarkShape<K> expression_shape(const MorphableModel& model, const Eigen::VectorXf& identity,
                                  const FitSettings& settings) {
  LandmarkShape<K> shape;
  shape.expressions = true;
  shape.coefficients = model.num_expressions();
  shape.partner.fill(-1);
  const Eigen::VectorXf neutral =
      model.mean + model.basis * model.stddev.cwiseProduct(
                                     identity.size() ? identity : Eigen::VectorXf::Zero(model.num_components()));
  shape.jaw_open = model.expression_index("jawOpen").value_or(-1);
  shape.mouth_close = model.expression_index("mouthClose").value_or(-1);
  shape.mean.setConstant(kNaN);
  shape.basis.setZero();
  for (int landmark = 0; landmark < kNumLandmarks; ++landmark) {
    const int vertex = model.landmark_vertex[landmark];
    if (vertex < 0) continue;
    shape.mean.col(landmark) = neutral.segment<3>(3 * vertex).cast<double>();
    for (int e = 0; e < model.num_expressions(); ++e)
      if (!is_unobservable_expression(model.expression_names[e]))
        shape.basis.template block<3, 1>(3 * landmark, e) = model.expressions.block<3, 1>(3 * vertex, e).cast<double>();
  }
  if (shape.jaw_open >= 0 && shape.mouth_close >= 0) {
    shape.basis.col(shape.mouth_close) += shape.basis.col(shape.jaw_open);
    shape.partner[shape.jaw_open] = shape.mouth_close;
    shape.partner[shape.mouth_close] = shape.jaw_open;
  }
  for (int e = 0; e < model.num_expressions(); ++e) {
    const double jaw = e == shape.jaw_open || e == shape.mouth_close ? settings.jaw_prior_ratio : 1.0;
    shape.ridge[e] = settings.expression_prior * jaw;
    shape.sparsity[e] = settings.expression_sparsity * jaw;
  }
  return shape;
}

template <int L, int K>
class FixedSizeFitter final : public FitterBase {
 public:
  FixedSizeFitter(const LandmarkShape<K>& shape, std::span<const int> set_indices, FitSettings settings)
      : settings_(settings), shape_(shape) {
    std::copy(set_indices.begin(), set_indices.end(), indices_.begin());
    Mat<L, 3> mean;
    for (int i = 0; i < L; ++i) {
      mean.row(i) = shape.mean.col(indices_[i]).transpose();
      for (int axis = 0; axis < 3; ++axis) basis_.row(axis * L + i) = shape.basis.row(3 * indices_[i] + axis);
    }
    moments_ = model_moments<L, K>(basis_, mean);
    centred_mean_ = mean.rowwise() - moments_.centroid.transpose();
  }

  void fit(const Landmarks2D& detected, FitOutput& inout) const override {
    Mat<L, 2> image_points;
    for (int i = 0; i < L; ++i) image_points.row(i) = detected.col(indices_[i]).transpose();
    const ImageMoments<K> image = image_moments<L, K>(basis_, centred_mean_, image_points);

    Mat<K, 1> c =
        shape_.expressions ? to_fit_weights(inout.expressions) : Mat<K, 1>(inout.coefficients.template head<K>());
    Mat<3, 4> camera = Mat<3, 4>::Zero();  // set by the first iteration (iterations >= 1)
    for (int iteration = 0; iteration < settings_.iterations; ++iteration) {
      camera =
          estimate_affine_camera<L>(shape_moments<L, K>(moments_, image, c), image.centroid, image.mean_squared_radius);
      const Mat<K, K> AtA = shape_normal_matrix<K>(moments_, camera);
      const Mat<K, 1> Atb = shape_rhs<K>(moments_, image, camera);
      if (shape_.expressions) {
        const double omega =
            1.0 / (camera_scale_squared(camera) * settings_.expression_sigma_mm * settings_.expression_sigma_mm);
        Mat<K, K> H = omega * AtA;
        H.diagonal() += shape_.ridge;
        H.diagonal().array() += 1e-12;  // a shape that moves no landmark keeps a finite step
        solve_bounded<K>(H, -omega * Atb - shape_.sparsity, shape_.partner, settings_.sweeps, c);
      } else {
        c = solve_shape<K>(AtA, Atb, settings_.sigma_px, settings_.lambda);
      }
    }
    write_output(camera, c, image_points, inout);
  }

  void add_normal_equations(const Landmarks2D& detected, const Eigen::VectorXd& alpha, Eigen::MatrixXd& AtA,
                            Eigen::VectorXd& Atb) const override {
    Mat<L, 2> image_points;
    for (int i = 0; i < L; ++i) image_points.row(i) = detected.col(indices_[i]).transpose();
    const ImageMoments<K> image = image_moments<L, K>(basis_, centred_mean_, image_points);
    Mat<K, 1> c = Mat<K, 1>::Zero();
    c.head(alpha.size()) = alpha;
    const Mat<3, 4> camera =
        estimate_affine_camera<L>(shape_moments<L, K>(moments_, image, c), image.centroid, image.mean_squared_radius);
    AtA += shape_normal_matrix<K>(moments_, camera).topLeftCorner(alpha.size(), alpha.size());
    Atb += shape_rhs<K>(moments_, image, camera).head(alpha.size());
  }

 private:
  /// Expression weights (model order) -> the fitted coordinates: u = jawOpen - mouthClose.
  Mat<K, 1> to_fit_weights(const FitOutput::Expressions& w) const {
    Mat<K, 1> c = w.template head<K>();
    if (shape_.jaw_open >= 0 && shape_.mouth_close >= 0)
      c[shape_.jaw_open] = std::max(0.0, w[shape_.jaw_open] - w[shape_.mouth_close]);
    return c;
  }

  void write_output(const Mat<3, 4>& camera, const Mat<K, 1>& c, const Mat<L, 2>& image_points, FitOutput& out) const {
    out.camera = camera;
    if (shape_.expressions) {
      out.expressions.setZero();
      out.expressions.template head<K>() = c;
      if (shape_.jaw_open >= 0 && shape_.mouth_close >= 0)
        out.expressions[shape_.jaw_open] = c[shape_.jaw_open] + c[shape_.mouth_close];
    } else {
      out.coefficients.setZero();
      out.coefficients.template head<K>() = c;
    }
    Eigen::Map<Mat<3 * kNumLandmarks, 1>>(out.model_landmarks.data()).noalias() = shape_.basis.lazyProduct(c);
    out.model_landmarks += shape_.mean;
    out.projected.noalias() = camera.template topLeftCorner<2, 3>().lazyProduct(out.model_landmarks);
    out.projected.colwise() += camera.template topRightCorner<2, 1>();
    double squared_error = 0;
    for (int i = 0; i < L; ++i)
      squared_error += (out.projected.col(indices_[i]) - image_points.row(i).transpose()).squaredNorm();
    out.reprojection_error_px = std::sqrt(squared_error / L);
  }

  FitSettings settings_;
  LandmarkShape<K> shape_;      // the shape at all 68 landmarks
  std::array<int, L> indices_;  // iBUG index of each set landmark
  Mat<3 * L, K> basis_;         // the basis at the set's landmarks: [B_x; B_y; B_z]
  Mat<L, 3> centred_mean_;      // m'_i, one per row (mm)
  ModelMoments<K> moments_;
};

template <int K, LandmarkSet S>
std::unique_ptr<FitterBase> fitter_for(const LandmarkShape<K>& shape, FitSettings settings) {
  return std::make_unique<FixedSizeFitter<landmark_count(S), K>>(shape, landmark_indices(S), settings);
}

template <int K>
std::unique_ptr<FitterBase> make_fixed_size_fitter(const LandmarkShape<K>& shape, LandmarkSet set,
                                                   FitSettings settings) {
  switch (set) {
    case LandmarkSet::F1: return fitter_for<K, LandmarkSet::F1>(shape, settings);
    case LandmarkSet::F2: return fitter_for<K, LandmarkSet::F2>(shape, settings);
    case LandmarkSet::F3: return fitter_for<K, LandmarkSet::F3>(shape, settings);
    case LandmarkSet::F4: return fitter_for<K, LandmarkSet::F4>(shape, settings);
    case LandmarkSet::F5: return fitter_for<K, LandmarkSet::F5>(shape, settings);
  }
  throw std::invalid_argument("Fitter: unknown landmark set");
}

/// The expression fit exists for the sets with eyes and brows (F4, F5): their shapes move them.
std::unique_ptr<FitterBase> make_expression_fitter(const LandmarkShape<kMaxFitExpressions>& shape, LandmarkSet set,
                                                   FitSettings settings) {
  switch (set) {
    case LandmarkSet::F4: return fitter_for<kMaxFitExpressions, LandmarkSet::F4>(shape, settings);
    case LandmarkSet::F5: return fitter_for<kMaxFitExpressions, LandmarkSet::F5>(shape, settings);
    default: break;
  }
  throw std::invalid_argument("Fitter: a model with expression shapes is fitted with landmark set F4 or F5, not " +
                              std::string(landmark_set_name(set)));
}

/// The pose-PCA fitter of a model's components (an expression model's identity).
std::unique_ptr<FitterBase> make_pca_fitter(const MorphableModel& model, LandmarkSet set, int num_components,
                                            FitSettings settings) {
  // Two compiled sizes keep the code small; unused components of the larger size have zero
  // basis columns, so lambda holds them at exactly zero.
  return num_components <= 20 ? make_fixed_size_fitter<20>(pca_shape<20>(model, num_components), set, settings)
                              : make_fixed_size_fitter<kMaxFitComponents>(
                                    pca_shape<kMaxFitComponents>(model, num_components), set, settings);
}

void check_fit_inputs(const MorphableModel& model, LandmarkSet set, const FitSettings& settings) {
  if (settings.iterations < 1) throw std::invalid_argument("Fitter: iterations must be at least 1");
  if (!(settings.lambda > 0)) throw std::invalid_argument("Fitter: lambda must be positive");
  if (!(settings.sigma_px > 0)) throw std::invalid_argument("Fitter: sigma_px must be positive");
  if (settings.sweeps < 1 || settings.identity_iterations < 1)
    throw std::invalid_argument("Fitter: sweeps and identity_iterations must be at least 1");
  if (!(settings.expression_sigma_mm > 0)) throw std::invalid_argument("Fitter: expression_sigma_mm must be positive");
  if (!(settings.expression_prior >= 0) || !(settings.jaw_prior_ratio >= 0) || !(settings.expression_sparsity >= 0))
    throw std::invalid_argument("Fitter: the expression priors must not be negative");
  if (model.num_components() < 1) throw std::invalid_argument("Fitter: the model has no shape components");
  if (model.basis.rows() != model.mean.size() || model.basis.cols() != model.num_components())
    throw std::invalid_argument("Fitter: the model's basis does not match its mean and stddev sizes");
  if (model.num_expressions() > kMaxFitExpressions)
    throw std::invalid_argument("Fitter: the model has " + std::to_string(model.num_expressions()) +
                                " expression shapes, more than the " + std::to_string(kMaxFitExpressions) +
                                " the fitter holds");
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

bool is_unobservable_expression(std::string_view name) {
  return name.starts_with("eyeLook") || name.starts_with("cheekPuff") || name.starts_with("tongueOut");
}

Fitter::Fitter(const MorphableModel& model, LandmarkSet set, FitSettings settings, const Eigen::VectorXf& identity)
    : num_components_(std::min(model.num_components(), kMaxFitComponents)),
      truncated_(model.num_components() > kMaxFitComponents),
      expressions_(model.has_expressions()) {
  check_fit_inputs(model, set, settings);
  if (identity.size() != 0 && identity.size() != model.num_components())
    throw std::invalid_argument("Fitter: the identity has " + std::to_string(identity.size()) +
                                " coefficients, the model " + std::to_string(model.num_components()));
  impl_ = expressions_
              ? make_expression_fitter(expression_shape<kMaxFitExpressions>(model, identity, settings), set, settings)
              : make_pca_fitter(model, set, num_components_, settings);
}

void Fitter::fit(const Landmarks2D& detected, FitOutput& inout) const { impl_->fit(detected, inout); }

FitOutput Fitter::initial_output() {
  FitOutput output;
  output.camera.setZero();
  output.camera(2, 3) = 1.0;
  output.coefficients.setZero();
  output.expressions.setZero();
  output.projected.setConstant(kNaN);
  output.model_landmarks.setConstant(kNaN);
  output.reprojection_error_px = kNaN;
  return output;
}

Eigen::VectorXf fit_identity(const MorphableModel& model, LandmarkSet set, std::span<const Landmarks2D> frames,
                             FitSettings settings) {
  check_fit_inputs(model, set, settings);
  if (frames.empty()) throw std::invalid_argument("fit_identity: no frames");
  const int k = std::min(model.num_components(), kMaxFitComponents);
  const std::unique_ptr<FitterBase> fitter = make_pca_fitter(model, set, k, settings);
  const double omega = 1.0 / (settings.sigma_px * settings.sigma_px);
  Eigen::VectorXd alpha = Eigen::VectorXd::Zero(k);
  for (int iteration = 0; iteration < settings.identity_iterations; ++iteration) {
    Eigen::MatrixXd AtA = Eigen::MatrixXd::Zero(k, k);
    Eigen::VectorXd Atb = Eigen::VectorXd::Zero(k);
    for (const Landmarks2D& frame : frames) fitter->add_normal_equations(frame, alpha, AtA, Atb);
    // The MAP estimate of one identity behind every frame (Huber et al. 2016 as above, the
    // data term summed over the frames): (sum_f A_f^T Omega A_f + lambda I) alpha = -sum_f A_f^T Omega b_f.
    Eigen::MatrixXd lhs = omega * AtA;
    lhs.diagonal().array() += settings.lambda;
    alpha = Eigen::LLT<Eigen::MatrixXd>(lhs).solve(-omega * Atb);
  }
  Eigen::VectorXf identity = Eigen::VectorXf::Zero(model.num_components());
  identity.head(k) = alpha.cast<float>();
  return identity;
}

FitOutput::Expressions fit_rest_expression(const MorphableModel& model, LandmarkSet set,
                                           std::span<const Landmarks2D> frames, const Eigen::VectorXf& identity,
                                           FitSettings settings) {
  if (frames.empty()) throw std::invalid_argument("fit_rest_expression: no frames");
  const Fitter fitter(model, set, settings, identity);
  const int n = static_cast<int>(frames.size());
  const int passes = (kRestWarmUpFits + n - 1) / n;
  std::vector<std::vector<double>> last_pass(static_cast<std::size_t>(model.num_expressions()));
  FitOutput fit = Fitter::initial_output();
  for (int pass = 0; pass < passes; ++pass)
    for (const Landmarks2D& frame : frames) {
      fitter.fit(frame, fit);
      if (pass + 1 == passes)
        for (int e = 0; e < model.num_expressions(); ++e)
          last_pass[static_cast<std::size_t>(e)].push_back(fit.expressions[e]);
    }
  FitOutput::Expressions rest = FitOutput::Expressions::Zero();
  for (int e = 0; e < model.num_expressions(); ++e) rest[e] = median(last_pass[static_cast<std::size_t>(e)]);
  for (const char* opening : {"jawOpen", "mouthClose"})
    if (const auto e = model.expression_index(opening)) rest[*e] = 0;
  return rest;
}

void above_rest(const FitOutput::Expressions& w, const FitOutput::Expressions& rest, FitOutput::Expressions& out) {
  for (int e = 0; e < kMaxFitExpressions; ++e)
    out[e] = rest[e] < 1 ? std::clamp((w[e] - rest[e]) / (1 - rest[e]), 0.0, 1.0) : 0.0;
}

}  // namespace lipdrive
