// Viseme weights, by the kind of model (docs/method.md 8): a model with expression shapes (the
// ICT head) takes them from its ARKit weights through one table (visemes_from_arkit, the table
// in docs/arkit.md); a model built from viseme poses matches its poses (VisemeSolver below).
//
// Viseme weights from fitted shape coefficients (docs/method.md 8):
// alpha - alpha_neutral ≈ Σ_v w_v c_v with w >= 0, where c_v = alpha(full pose of viseme v) -
// alpha(neutral). Solved by non-negative least squares (Lawson & Hanson 1974, "Solving Least
// Squares Problems", ch. 23, algorithm NNLS) on the fixed-size normal equations, then clamped
// to [0, 1].
#pragma once

#include "core/drive_signals.hpp"  // kNumVisemes, kVisemeNames
#include "core/fitting.hpp"        // kMaxFitComponents
#include "core/landmarks.hpp"
#include "core/morphable_model.hpp"

#include <Eigen/Core>

#include <array>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace lipdrive {

using VisemeWeights = std::array<float, kNumVisemes>;

/// Built once per model; solve() allocates nothing and costs a bounded number of 16 x 16
/// factorisations per frame.
class VisemeSolver {
 public:
  using Coefficients = Eigen::Matrix<double, kMaxFitComponents, 1>;  // FitOutput::coefficients
  using Gram = Eigen::Matrix<double, kNumVisemes, kNumVisemes>;
  using Vector = Eigen::Matrix<double, kNumVisemes, 1>;

  /// Uses the model's pose named "neutral" and, per viseme, "<viseme>_100" or else the pose
  /// named exactly "<viseme>". Throws std::invalid_argument when one of them is missing.
  /// Everything of the example poses that the pose match over `set` reuses every frame (their
  /// landmarks centred, scatter matrices and inverses) is computed here, once.
  VisemeSolver(const MorphableModel& model, LandmarkSet set);

  /// The weights of fitted coefficients (the first num_components() are read), each in [0, 1].
  VisemeWeights solve(const Coefficients& alpha) const;

  /// The weights of a fitted frame, judged in the image: for every example pose (neutral or
  /// "<viseme>_<percent>") the weak-perspective camera that maps its landmarks onto
  /// `observed` over the landmark set (least-squares affine, projected onto scaled rotation
  /// rows: an affine camera's shear and unequal scales would absorb mouth shapes), and the
  /// residual; the nearest pose is the maximum-likelihood (pose, camera) under i.i.d. Gaussian
  /// landmark noise. Its viseme gets the intensity refined between the neighbouring
  /// intensities (parabola through the three distances); what the fitted coefficients show
  /// beyond that pose goes to the NNLS of solve(), always below the dominant weight. Nearest to
  /// neutral, or a landmark of the set not finite: solve(fit.coefficients). `observed` is the
  /// detected landmarks (unbiased) or fit.projected. Allocates nothing. With centred
  /// coordinates the affine camera is C S⁻¹ and the residual tr(R S Rᵀ) − 2 tr(R Cᵀ) + Σ|õ|²
  /// (S the pose's scatter, precomputed; C = Σ õ xᵀ the observed-pose cross-covariance). C is
  /// linear in the pose's shape coefficients, so per frame the observed points meet the mean
  /// and the K basis columns once, and each pose costs a 6 x K product and a few 3 x 3 ones.
  VisemeWeights solve(const FitOutput& fit, const Landmarks2D& observed) const;

  /// 2-norm condition number of the 16 viseme directions: how well the model's components
  /// tell the 16 visemes apart (large = some are nearly linear combinations of others).
  double condition_number() const;
  int num_components() const { return num_components_; }

 private:
  int num_components_;
  Coefficients neutral_;                                              // alpha of the neutral pose
  Eigen::Matrix<double, kMaxFitComponents, kNumVisemes> directions_;  // column v = σ ⊙ c_v
  Coefficients stddev_;                                               // σ, zero past num_components_
  Gram gram_;                                                         // directionsᵀ directions
  // The landmarks of the set the model maps to a vertex: the pose match's points.
  std::array<int, kNumLandmarks> matched_{};
  int num_matched_ = 0;
  // Over matched_, one row per point (each coordinate a contiguous column): the model's mean
  // landmarks in columns 0-2 and basis column k's in columns 3k+3 to 3k+5, in mm. Every
  // example pose's landmarks are mean + Σ_k shape_k · basis_k.
  Eigen::MatrixXd landmark_basis_;
  // The example poses, for solve(fit, ...): viseme (-1 = neutral), intensity in [0, 1], the
  // shape σ ⊙ alpha, and over matched_ the scatter S = Σ x̃ x̃ᵀ of its landmarks centred on
  // their centroid, and S⁻¹.
  struct ExamplePose {
    int viseme;
    double intensity;
    Coefficients shape;
    Eigen::Matrix3d scatter;
    Eigen::Matrix3d scatter_inverse;
  };
  std::vector<ExamplePose> poses_;
};

/// The solver of a model that has the poses VisemeSolver needs, else nullopt (a user model
/// built from other poses: it has no viseme weights).
std::optional<VisemeSolver> make_viseme_solver(const MorphableModel& model, LandmarkSet set);

/// The inputs of the ARKit viseme table, each an articulation read from the 52 ARKit weights
/// and divided by `full`, its level at full articulation: "aperture" is jawOpen − mouthClose
/// (ARKit's mouthClose closes the lips against the open jaw, so this is the lips' opening), a
/// Left/Right stem ("mouthStretch") is the mean of its two sides, the others are Apple names.
/// `full` is the input's 99th percentile over the ICT head's fit of GRID speech (the tuning
/// clips, docs/arkit.md "Visemes"); 0.5 for the three the fit never moves on GRID.
struct ArkitVisemeInput {
  std::string_view shape;
  float full;
};
inline constexpr std::array<ArkitVisemeInput, 11> kArkitVisemeInputs{{
    {"aperture", 0.34f},
    {"mouthPucker", 0.47f},
    {"mouthFunnel", 0.5f},
    {"mouthStretch", 0.17f},
    {"mouthSmile", 0.5f},
    {"mouthLowerDown", 0.16f},
    {"mouthUpperUp", 0.58f},
    {"mouthRollLower", 0.27f},
    {"mouthShrugLower", 0.45f},
    {"mouthShrugUpper", 0.5f},
    {"mouthPress", 0.39f},
}};
inline constexpr int kNumArkitVisemeInputs = static_cast<int>(kArkitVisemeInputs.size());

/// The table of docs/arkit.md "Visemes": row v (kVisemeNames order) holds viseme v's share of
/// each input at full articulation (the columns of kArkitVisemeInputs), then a constant.
/// Viseme v's weight before the lips' seal is clamp(Σ share · input / full + constant, 0, 1).
/// Each row is the viseme's articulation (sim/synthetic_head.cpp gives the same 16 to the
/// generated head) in ARKit's shapes: what makes it positive, what contradicts it negative.
// clang-format off
inline constexpr std::array<std::array<float, kNumArkitVisemeInputs + 1>, kNumVisemes> kArkitVisemeTable{{
    //  aperture pucker funnel stretch smile lowerDown upperUp rollLower shrugLower shrugUpper press constant
    {{ 1.5f, -1.0f,  0.0f,  0.0f, 0.0f, 0.3f, 0.0f, -0.5f, 0.0f, 0.0f,  0.0f,  0.0f}},  // Aah
    {{ 2.0f, -1.0f,  0.0f,  0.3f, 0.0f, 0.0f, 0.0f,  0.0f, 0.0f, 0.0f,  0.0f, -1.0f}},  // BigAah
    {{-0.7f,  0.0f,  0.0f,  0.0f, 0.0f, 0.0f, 0.0f,  0.6f, 0.0f, 0.0f,  1.7f,  0.0f}},  // B-M-P
    {{-0.5f,  0.3f,  0.6f, -0.5f, 0.0f, 0.0f, 0.3f,  0.0f, 0.6f, 0.6f,  0.0f,  0.0f}},  // Ch-J-Sh
    {{-0.3f, -1.0f,  0.0f,  0.6f, 0.0f, 0.4f, 0.3f,  0.0f, 0.0f, 0.0f,  0.0f,  0.0f}},  // D-S-T
    {{-0.5f, -1.0f,  0.0f,  0.7f, 1.0f, 0.0f, 0.0f,  0.0f, 0.0f, 0.0f,  0.0f,  0.0f}},  // Eee
    {{ 1.0f, -1.0f,  0.0f,  0.4f, 0.0f, 0.0f, 0.0f,  0.0f, 0.0f, 0.0f,  0.0f,  0.0f}},  // Eh
    {{-0.5f, -0.5f,  0.0f,  0.0f, 0.0f, 0.0f, 0.6f,  1.0f, 0.0f, 0.0f, -0.5f,  0.0f}},  // F-V
    {{ 0.6f, -1.0f,  0.0f,  0.5f, 0.0f, 0.2f, 0.0f,  0.0f, 0.0f, 0.0f,  0.0f,  0.0f}},  // i
    {{ 0.8f, -1.0f,  0.0f, -0.3f, 0.0f, 0.4f, 0.0f,  0.0f, 0.0f, 0.0f,  0.0f,  0.0f}},  // K
    {{ 0.4f, -1.0f,  0.0f,  0.3f, 0.5f, 0.0f, 0.0f,  0.0f, 0.0f, 0.0f,  0.0f,  0.0f}},  // N
    {{ 0.8f,  0.8f,  1.0f, -0.5f, 0.0f, 0.0f, 0.0f,  0.0f, 0.0f, 0.0f,  0.0f, -0.5f}},  // Oh
    {{ 0.0f,  1.0f,  0.5f, -0.5f, 0.0f, 0.0f, 0.0f,  0.0f, 0.0f, 0.0f,  0.0f,  0.0f}},  // Ooh-Q
    {{-0.3f,  0.5f,  0.0f, -0.5f, 0.0f, 0.0f, 0.5f,  0.0f, 0.0f, 0.0f,  0.0f,  0.0f}},  // R
    {{ 0.3f, -1.0f,  0.0f,  0.0f, 0.0f, 0.6f, 0.0f, -0.5f, 0.4f, 0.0f,  0.0f,  0.0f}},  // Th
    {{-0.5f,  1.2f,  0.0f, -0.5f, 0.0f, 0.0f, 0.0f,  0.0f, 0.0f, 0.0f,  0.0f,  0.0f}},  // W
}};
// clang-format on

/// The 16 viseme weights of a frame's 52 ARKit weights as fitted (a model with expression
/// shapes; before set_arkit_signals closes touching lips with mouthClose, which the seal here
/// stands for): the table's weights, then the lips' seal as the pose match has it (transfer_to_bilabial), except
/// that lips a viseme already closes (W, Ooh-Q puckered; F-V the lower lip on the upper teeth)
/// are that viseme's: the seal moved is seal · (1 − the largest of W, Ooh-Q and F-V).
/// Allocates nothing.
VisemeWeights visemes_from_arkit(std::span<const float, kNumArkit> arkit, double seal);

/// Sealed lips in a shape the landmarks read as open are a bilabial closure (the landmark
/// regression lags towards a half-open mouth on b, p, m): the articulation the other visemes
/// show moves to B-M-P in proportion to `seal` (core/lip_contact.hpp), the probability that
/// the lips touch. B-M-P becomes max(B-M-P, seal x the largest other weight) and every other
/// weight shrinks by (1 - seal). A sealed mouth at rest has no other weight to move, so it
/// stays at rest.
void transfer_to_bilabial(VisemeWeights& weights, double seal);

/// Lawson–Hanson NNLS on the normal equations: minimises ½ wᵀ G w − hᵀ w over w >= 0, i.e.
/// ||A w − b||² with G = AᵀA, h = Aᵀb. At most 3·16 outer iterations (the bound Lawson and
/// Hanson suggest); each inner step drops at least one variable, so it ends too.
VisemeSolver::Vector nnls_normal_equations(const VisemeSolver::Gram& gram, const VisemeSolver::Vector& h);

}  // namespace lipdrive
