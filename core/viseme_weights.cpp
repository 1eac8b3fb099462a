#include "core/viseme_weights.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace lipdrive {
namespace {

using Passive = std::array<bool, kNumVisemes>;
using Vector = VisemeSolver::Vector;
using Gram = VisemeSolver::Gram;

std::optional<int> find_full_pose(const MorphableModel& model, std::string_view viseme) {
  const std::string name(viseme);
  if (const auto index = model.pose_index(name + "_100")) return index;
  return model.pose_index(name);
}

int full_pose_index(const MorphableModel& model, std::string_view viseme) {
  if (const auto index = find_full_pose(model, viseme)) return *index;
  const std::string name(viseme);
  throw std::invalid_argument("the model has no full-intensity pose of viseme " + name + " (\"" + name +
                              "_100\" or \"" + name + "\"), so it cannot give viseme weights");
}

VisemeSolver::Coefficients padded(const Eigen::VectorXf& values, int count) {
  VisemeSolver::Coefficients out = VisemeSolver::Coefficients::Zero();
  out.head(count) = values.head(count).cast<double>();
  return out;
}

/// The unconstrained least-squares solution on the passive set P (Lawson & Hanson step 6):
/// G_PP z_P = h_P, z = 0 elsewhere. The inactive rows and columns become identity rows so
/// the system keeps its compile-time size.
Vector solve_passive(const Gram& gram, const Vector& h, const Passive& passive) {
  Gram g = gram;
  Vector rhs = h;
  for (int j = 0; j < kNumVisemes; ++j) {
    if (passive[j]) continue;
    g.row(j).setZero();
    g.col(j).setZero();
    g(j, j) = 1;
    rhs(j) = 0;
  }
  return Eigen::LDLT<Gram>(g).solve(rhs);
}

/// "neutral" -> (-1, 0); "<viseme>_<percent>" -> (viseme, percent / 100); "<viseme>" -> (viseme, 1).
std::optional<std::pair<int, double>> parse_pose_name(const std::string& name) {
  if (name == "neutral") return std::pair{-1, 0.0};
  for (int v = 0; v < kNumVisemes; ++v) {
    const std::string viseme(kVisemeNames[v]);
    if (name == viseme) return std::pair{v, 1.0};
    if (name.size() == viseme.size() + 4 && name.compare(0, viseme.size() + 1, viseme + "_") == 0) {
      int percent = 0;
      const char* digits = name.data() + viseme.size() + 1;
      const auto [end, error] = std::from_chars(digits, name.data() + name.size(), percent);
      if (error == std::errc() && end == name.data() + name.size() && percent >= 0 && percent <= 100)
        return std::pair{v, percent / 100.0};
    }
  }
  return std::nullopt;
}

/// Where each input of kArkitVisemeInputs comes from: the ARKit weights at first and second
/// (second -1: one weight), combined as (w[first] + sign · w[second]) · scale. Resolved at compile
/// time: an input that names no ARKit shape throws, which fails the build.
struct InputSource {
  int first = -1, second = -1;
  float sign = 0, scale = 0;
};

constexpr std::array<InputSource, kNumArkitVisemeInputs> input_sources() {
  std::array<InputSource, kNumArkitVisemeInputs> out{};
  for (int i = 0; i < kNumArkitVisemeInputs; ++i) {
    const ArkitVisemeInput& input = kArkitVisemeInputs[static_cast<std::size_t>(i)];
    InputSource& s = out[static_cast<std::size_t>(i)];
    if (input.shape == "aperture") {
      s = {*arkit_index("jawOpen"), *arkit_index("mouthClose"), -1, 1 / input.full};
    } else if (const auto a = arkit_index(input.shape)) {
      s = {*a, -1, 0, 1 / input.full};
    } else {
      for (int a = 0; a < kNumArkit; ++a) {
        const std::string_view name = kArkitNames[static_cast<std::size_t>(a)];
        if (!name.starts_with(input.shape)) continue;
        if (name.substr(input.shape.size()) == "Left") s.first = a;
        if (name.substr(input.shape.size()) == "Right") s.second = a;
      }
      if (s.first < 0 || s.second < 0)
        throw std::invalid_argument("kArkitVisemeInputs: no ARKit shape or Left/Right pair of that name");
      s.sign = 1;
      s.scale = 0.5f / input.full;
    }
  }
  return out;
}

constexpr std::array<InputSource, kNumArkitVisemeInputs> kInputSources = input_sources();

constexpr int viseme_named(std::string_view name) {
  return static_cast<int>(std::find(kVisemeNames.begin(), kVisemeNames.end(), name) - kVisemeNames.begin());
}

}  // namespace

VisemeWeights visemes_from_arkit(std::span<const float, kNumArkit> arkit, double seal) {
  std::array<float, kNumArkitVisemeInputs + 1> input;
  for (int i = 0; i < kNumArkitVisemeInputs; ++i) {
    const InputSource& s = kInputSources[static_cast<std::size_t>(i)];
    const float second = s.second < 0 ? 0.0f : s.sign * arkit[static_cast<std::size_t>(s.second)];
    input[static_cast<std::size_t>(i)] = (arkit[static_cast<std::size_t>(s.first)] + second) * s.scale;
  }
  input.back() = 1;  // the constant
  VisemeWeights out;
  for (int v = 0; v < kNumVisemes; ++v) {
    const auto& row = kArkitVisemeTable[static_cast<std::size_t>(v)];
    float sum = 0;
    for (std::size_t i = 0; i < input.size(); ++i) sum += row[i] * input[i];
    out[static_cast<std::size_t>(v)] = std::clamp(sum, 0.0f, 1.0f);
  }
  constexpr int kW = viseme_named("W"), kOoh = viseme_named("Ooh-Q"), kFv = viseme_named("F-V");
  static_assert(kW < kNumVisemes && kOoh < kNumVisemes && kFv < kNumVisemes);
  const float closed_by_viseme = std::max({out[kW], out[kOoh], out[kFv]});
  transfer_to_bilabial(out, std::clamp(seal, 0.0, 1.0) * (1 - closed_by_viseme));
  return out;
}

Vector nnls_normal_equations(const Gram& gram, const Vector& h) {
  // Tolerance for "the gradient still points into the feasible set": near the rounding
  // error of h − G w, because the default model's viseme directions are ill-conditioned
  // and a looser test stops with a visibly wrong mix.
  const double tolerance = 1e-12 * h.cwiseAbs().maxCoeff();
  Passive passive{};
  Vector w = Vector::Zero();
  for (int outer = 0; outer < 3 * kNumVisemes; ++outer) {
    // Steps 2-5: the most promising zero variable (largest gradient of -objective).
    const Vector gradient = h - gram * w;
    int entering = -1;
    for (int j = 0; j < kNumVisemes; ++j)
      if (!passive[j] && gradient(j) > tolerance && (entering < 0 || gradient(j) > gradient(entering))) entering = j;
    if (entering < 0) break;  // Kuhn-Tucker conditions hold
    passive[entering] = true;
    // Steps 6-11: move towards the passive-set solution, dropping variables that would go negative.
    for (int inner = 0; inner < kNumVisemes; ++inner) {
      const Vector z = solve_passive(gram, h, passive);
      double step = 1;
      for (int j = 0; j < kNumVisemes; ++j)
        if (passive[j] && z(j) <= 0) step = std::min(step, w(j) / (w(j) - z(j)));
      if (step >= 1) {
        w = z;
        break;
      }
      w += step * (z - w);
      for (int j = 0; j < kNumVisemes; ++j)
        if (passive[j] && w(j) <= 0) {
          passive[j] = false;
          w(j) = 0;
        }
    }
  }
  return w;
}

VisemeSolver::VisemeSolver(const MorphableModel& model, LandmarkSet set)
    : num_components_(std::min(model.num_components(), kMaxFitComponents)), directions_(decltype(directions_)::Zero()) {
  const auto neutral = model.pose_index("neutral");
  if (!neutral)
    throw std::invalid_argument("the model has no pose named \"neutral\", so it cannot give viseme weights");
  neutral_ = padded(model.pose_coefficients.col(*neutral), num_components_);
  stddev_ = padded(model.stddev, num_components_);
  // Residuals in stddev-weighted coefficients are residuals in model space (mm): the basis
  // is orthonormal, so |basis (σ ⊙ Δα)| = |σ ⊙ Δα|.
  for (int v = 0; v < kNumVisemes; ++v) {
    const Coefficients full =
        padded(model.pose_coefficients.col(full_pose_index(model, kVisemeNames[v])), num_components_);
    directions_.col(v) = stddev_.cwiseProduct(full - neutral_);
  }
  gram_ = directions_.transpose() * directions_;
  for (const int i : landmark_indices(set))
    if (model.landmark_vertex[static_cast<std::size_t>(i)] >= 0) matched_[num_matched_++] = i;
  landmark_basis_.resize(num_matched_, 3 * (1 + num_components_));
  for (int k = 0; k < num_matched_; ++k) {
    const int v = model.landmark_vertex[static_cast<std::size_t>(matched_[k])];
    for (int c = 0; c < 3; ++c) {
      landmark_basis_(k, c) = model.mean(3 * v + c);
      for (int j = 0; j < num_components_; ++j) landmark_basis_(k, 3 * j + 3 + c) = model.basis(3 * v + c, j);
    }
  }
  for (int pose = 0; pose < model.num_poses(); ++pose) {
    const auto parsed = parse_pose_name(model.pose_names[static_cast<std::size_t>(pose)]);
    if (!parsed) continue;
    ExamplePose example{parsed->first, parsed->second,
                        stddev_.cwiseProduct(padded(model.pose_coefficients.col(pose), num_components_)), {}, {}};
    Eigen::MatrixX3d points = landmark_basis_.leftCols<3>();
    for (int j = 0; j < num_components_; ++j) points += example.shape(j) * landmark_basis_.middleCols<3>(3 * j + 3);
    points.rowwise() -= points.colwise().mean();
    example.scatter = points.transpose() * points;
    example.scatter_inverse = example.scatter.ldlt().solve(Eigen::Matrix3d::Identity());
    poses_.push_back(example);
  }
}

VisemeWeights VisemeSolver::solve(const FitOutput& fit, const Landmarks2D& observed) const {
  // The observed landmarks over the set, centred: the translation of every camera below is
  // the one that maps the pose's centroid onto theirs, which is what least squares gives.
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::ColMajor, kNumLandmarks, 2> seen(num_matched_, 2);
  for (int k = 0; k < num_matched_; ++k) seen.row(k) = observed.col(matched_[k]).transpose();
  if (!seen.allFinite() || num_matched_ == 0) return solve(fit.coefficients);
  seen.rowwise() -= seen.colwise().mean();
  const double seen_energy = seen.squaredNorm();
  // The cross-covariance of the observed points with the mean and each basis column, as
  // 2 x 3 blocks flattened column-major: column 0 the mean's, column 1 + j basis column j's.
  // The observed points are centred, so a pose's centroid drops out of C = Σ õ xᵀ.
  Eigen::Matrix<double, 6, 1 + kMaxFitComponents> cross_basis = decltype(cross_basis)::Zero();
  for (int j = 0; j <= num_components_; ++j)
    for (int c = 0; c < 3; ++c)
      for (int row = 0; row < 2; ++row)
        cross_basis(row + 2 * c, j) = seen.col(row).dot(landmark_basis_.col(3 * j + c));
  // Squared image distance of every example pose; the nearest is the ML pose.
  std::array<double, 512> distance_storage{};
  const std::size_t count = std::min(poses_.size(), distance_storage.size());
  std::size_t best = 0;
  for (std::size_t p = 0; p < count; ++p) {
    const ExamplePose& pose = poses_[p];
    // The affine camera that best maps this pose's landmarks onto the observed ones (linear
    // least squares, as in the fit's step 1): M = C S⁻¹.
    Eigen::Matrix<double, 6, 1> flat = cross_basis.col(0);
    // Only the model's components: the padding up to kMaxFitComponents is zero.
    flat.noalias() += cross_basis.middleCols(1, num_components_) * pose.shape.head(num_components_);
    const Eigen::Map<const Eigen::Matrix<double, 2, 3>> cross(flat.data());
    const Eigen::Matrix<double, 2, 3> m = cross * pose.scatter_inverse;
    // Nearest weak-perspective camera (scaled rotation rows). With M = U S Vᵀ that is
    // (σ1+σ2)/2 · U [I 0] Vᵀ = (σ1+σ2)/2 · (M Mᵀ)^(-1/2) M; the square root of the 2x2
    // A = M Mᵀ has the closed form (A + √det A · I) / √(tr A + 2√det A), and
    // σ1 + σ2 = √(tr A + 2√det A): no SVD per pose.
    const Eigen::Matrix2d a = m * m.transpose();
    const double root_det = std::sqrt(std::max(a.determinant(), 0.0));
    const double singular_sum = std::sqrt(std::max(a.trace() + 2 * root_det, 1e-300));
    const Eigen::Matrix2d root = (a + root_det * Eigen::Matrix2d::Identity()) / singular_sum;
    const Eigen::Matrix<double, 2, 3> r = 0.5 * singular_sum * root.inverse() * m;
    // Σ |R x̃ − õ|² expanded, so it costs no pass over the points.
    const double d =
        (r * pose.scatter * r.transpose()).trace() - 2 * (r * cross.transpose()).trace() + seen_energy;
    distance_storage[p] = d;
    if (d < distance_storage[best]) best = p;
  }
  if (count == 0 || poses_[best].viseme < 0) return solve(fit.coefficients);  // nearest to neutral: the NNLS mix
  const int viseme = poses_[best].viseme;
  // Refine the intensity: the neighbouring intensities of the same viseme (neutral = 0 %).
  double below_i = -1, below_d = 0, above_i = 2, above_d = 0;
  const double at_i = poses_[best].intensity, at_d = distance_storage[best];
  for (std::size_t p = 0; p < count; ++p) {
    const bool same = poses_[p].viseme == viseme || poses_[p].viseme < 0;
    if (!same) continue;
    const double i = poses_[p].viseme < 0 ? 0.0 : poses_[p].intensity;
    if (i < at_i && i > below_i) below_i = i, below_d = distance_storage[p];
    if (i > at_i && i < above_i) above_i = i, above_d = distance_storage[p];
  }
  double intensity = at_i;
  if (below_i >= 0 && above_i <= 1) {
    // Vertex of the parabola through the three (intensity, distance) points.
    const double a = below_i - at_i, b = above_i - at_i;
    const double da = below_d - at_d, db = above_d - at_d;
    const double denominator = a * db - b * da;
    if (denominator != 0) intensity = at_i + 0.5 * (a * a * db - b * b * da) / denominator;
    intensity = std::clamp(intensity, below_i, above_i);
  }
  // The rest of the fitted shape beyond the matched pose, as non-negative viseme weights.
  const Coefficients target = stddev_.cwiseProduct(fit.coefficients) - poses_[best].shape;
  const Vector rest = nnls_normal_equations(gram_, directions_.transpose() * target);
  const auto dominant = static_cast<float>(std::clamp(intensity, 0.0, 1.0));
  VisemeWeights out;
  for (int v = 0; v < kNumVisemes; ++v)
    out[v] =
        v == viseme ? dominant : std::min(static_cast<float>(std::min(rest(v), 1.0)), std::nextafter(dominant, 0.0f));
  return out;
}

VisemeWeights VisemeSolver::solve(const Coefficients& alpha) const {
  const Coefficients target = stddev_.cwiseProduct(alpha - neutral_);  // σ is zero past num_components_
  const Vector w = nnls_normal_equations(gram_, directions_.transpose() * target);
  VisemeWeights out;
  for (int v = 0; v < kNumVisemes; ++v) out[v] = static_cast<float>(std::min(w(v), 1.0));
  return out;
}

std::optional<VisemeSolver> make_viseme_solver(const MorphableModel& model, LandmarkSet set) {
  if (!model.pose_index("neutral")) return std::nullopt;
  for (std::string_view viseme : kVisemeNames)
    if (!find_full_pose(model, viseme)) return std::nullopt;
  return VisemeSolver(model, set);
}

double VisemeSolver::condition_number() const {
  const Eigen::SelfAdjointEigenSolver<Gram> eigen(gram_, Eigen::EigenvaluesOnly);
  // The Gram matrix squares the singular values of the directions.
  return std::sqrt(eigen.eigenvalues().maxCoeff() / std::max(eigen.eigenvalues().minCoeff(), 0.0));
}

void transfer_to_bilabial(VisemeWeights& weights, double seal) {
  constexpr int kBilabial = 2;  // kVisemeNames[2]
  static_assert(kVisemeNames[kBilabial] == "B-M-P");
  const float s = static_cast<float>(std::clamp(seal, 0.0, 1.0));
  float largest_other = 0;
  for (int v = 0; v < kNumVisemes; ++v)
    if (v != kBilabial) largest_other = std::max(largest_other, weights[v]);
  for (int v = 0; v < kNumVisemes; ++v)
    if (v != kBilabial) weights[v] *= 1 - s;
  weights[kBilabial] = std::max(weights[kBilabial], s * largest_other);
}

}  // namespace lipdrive
