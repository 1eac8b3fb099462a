#include "core/viseme_weights.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

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

}  // namespace

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

VisemeSolver::VisemeSolver(const MorphableModel& model)
    : num_components_(std::min(model.num_components(), kMaxFitComponents)),
      directions_(decltype(directions_)::Zero()) {
  const auto neutral = model.pose_index("neutral");
  if (!neutral) throw std::invalid_argument("the model has no pose named \"neutral\", so it cannot give viseme weights");
  neutral_ = padded(model.pose_coefficients.col(*neutral), num_components_);
  stddev_ = padded(model.stddev, num_components_);
  // Residuals in stddev-weighted coefficients are residuals in model space (mm): the basis
  // is orthonormal, so |basis (σ ⊙ Δα)| = |σ ⊙ Δα|.
  for (int v = 0; v < kNumVisemes; ++v) {
    const Coefficients full = padded(model.pose_coefficients.col(full_pose_index(model, kVisemeNames[v])), num_components_);
    directions_.col(v) = stddev_.cwiseProduct(full - neutral_);
  }
  gram_ = directions_.transpose() * directions_;
}

VisemeWeights VisemeSolver::solve(const Coefficients& alpha) const {
  const Coefficients target = stddev_.cwiseProduct(alpha - neutral_);  // σ is zero past num_components_
  const Vector w = nnls_normal_equations(gram_, directions_.transpose() * target);
  VisemeWeights out;
  for (int v = 0; v < kNumVisemes; ++v) out[v] = static_cast<float>(std::min(w(v), 1.0));
  return out;
}

std::optional<VisemeSolver> make_viseme_solver(const MorphableModel& model) {
  if (!model.pose_index("neutral")) return std::nullopt;
  for (std::string_view viseme : kVisemeNames)
    if (!find_full_pose(model, viseme)) return std::nullopt;
  return VisemeSolver(model);
}

double VisemeSolver::condition_number() const {
  const Eigen::SelfAdjointEigenSolver<Gram> eigen(gram_, Eigen::EigenvaluesOnly);
  // The Gram matrix squares the singular values of the directions.
  return std::sqrt(eigen.eigenvalues().maxCoeff() / std::max(eigen.eigenvalues().minCoeff(), 0.0));
}

}  // namespace lipdrive
