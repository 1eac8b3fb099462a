// Viseme weights (core/viseme_weights): the NNLS solver, exact poses, allocation-free solve,
// and recovery of every default-model pose through a noisy fit.
#include "allocation_counter.hpp"
#include "core/viseme_weights.hpp"
#include "firmware_app/model_files.hpp"
#include "reference_fitter.hpp"

#include <Eigen/SVD>
#include <gtest/gtest.h>

#include <algorithm>
#include <charconv>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <map>
#include <random>
#include <stdexcept>
#include <string>

namespace lipdrive {
namespace {

using Gram = VisemeSolver::Gram;
using Vector = VisemeSolver::Vector;

// A random, well-conditioned least-squares problem ||A w - b|| with A 20 x 16.
struct Problem {
  Eigen::Matrix<double, 20, kNumVisemes> a;
  Gram gram() const { return a.transpose() * a; }
};

Problem random_problem(unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Problem p;
  p.a = Eigen::Matrix<double, 20, kNumVisemes>::NullaryExpr([&] { return gauss(rng); });
  return p;
}

TEST(Nnls, RecoversANonNegativeSolutionExactly) {
  const Problem p = random_problem(1);
  Vector truth = Vector::Zero();
  truth(2) = 0.7;
  truth(9) = 0.2;
  truth(15) = 1.3;
  const Vector w = nnls_normal_equations(p.gram(), p.a.transpose() * (p.a * truth));
  EXPECT_LT((w - truth).cwiseAbs().maxCoeff(), 1e-9);
}

TEST(Nnls, SatisfiesTheKuhnTuckerConditionsWhenLeastSquaresGoesNegative) {
  for (unsigned seed = 2; seed < 12; ++seed) {
    SCOPED_TRACE(seed);
    const Problem p = random_problem(seed);
    std::mt19937 rng(seed);
    std::normal_distribution<double> gauss(0.0, 1.0);
    const Eigen::Matrix<double, 20, 1> b = Eigen::Matrix<double, 20, 1>::NullaryExpr([&] { return gauss(rng); });
    const Vector h = p.a.transpose() * b;
    const Vector unconstrained = p.gram().ldlt().solve(h);
    ASSERT_LT(unconstrained.minCoeff(), 0) << "the case must need the constraint";
    const Vector w = nnls_normal_equations(p.gram(), h);
    const Vector gradient = h - p.gram() * w;  // minus the gradient of ½|Aw - b|²
    EXPECT_GE(w.minCoeff(), 0);
    for (int j = 0; j < kNumVisemes; ++j) {
      if (w(j) > 0) EXPECT_NEAR(gradient(j), 0, 1e-9) << j;  // free variables: stationary
      else EXPECT_LE(gradient(j), 1e-9) << j;                 // bound variables: pushing outwards
    }
  }
}

std::filesystem::path default_model_path(const char* file) { return std::filesystem::path(LIPDRIVE_MODEL_DIR) / file; }

VisemeSolver::Coefficients pose_alpha(const MorphableModel& model, int pose) {
  VisemeSolver::Coefficients alpha = VisemeSolver::Coefficients::Zero();
  const int k = std::min(model.num_components(), kMaxFitComponents);
  alpha.head(k) = model.pose_coefficients.col(pose).head(k).cast<double>();
  return alpha;
}

int largest(const VisemeWeights& w) { return static_cast<int>(std::max_element(w.begin(), w.end()) - w.begin()); }

// A model with random, well-separated viseme poses: the full poses give exact weights.
MorphableModel random_viseme_model(unsigned seed) {
  MorphableModel model = testing::random_model(100, 20, seed);
  model.pose_names = {"neutral"};
  for (std::string_view name : kVisemeNames) model.pose_names.push_back(std::string(name) + "_100");
  std::srand(seed);
  model.pose_coefficients = Eigen::MatrixXf::Random(20, 17);
  return model;
}

TEST(VisemeSolver, FullPosesOfASeparatingModelGiveOneWeightOfOne) {
  const MorphableModel model = random_viseme_model(4);
  const VisemeSolver solver(model);
  for (int v = 0; v < kNumVisemes; ++v) {
    SCOPED_TRACE(kVisemeNames[v]);
    const VisemeWeights w = solver.solve(pose_alpha(model, 1 + v));
    for (int u = 0; u < kNumVisemes; ++u) EXPECT_NEAR(w[u], u == v ? 1.0 : 0.0, 1e-4) << kVisemeNames[u];
  }
  const VisemeWeights rest = solver.solve(pose_alpha(model, 0));
  EXPECT_LT(*std::max_element(rest.begin(), rest.end()), 1e-4);
}

// The σ-weighted viseme directions (model space, mm) of a model's full poses, column per viseme.
Eigen::MatrixXd viseme_directions(const MorphableModel& model) {
  const int neutral = *model.pose_index("neutral");
  Eigen::MatrixXd directions(model.num_components(), kNumVisemes);
  for (int v = 0; v < kNumVisemes; ++v) {
    const std::string name(kVisemeNames[v]);
    const int pose = *model.pose_index(model.pose_index(name + "_100") ? name + "_100" : name);
    directions.col(v) = (model.stddev.cwiseProduct(model.pose_coefficients.col(pose) - model.pose_coefficients.col(neutral))).cast<double>();
  }
  return directions;
}

// On the default models the full poses need not give one-hot weights: their 16 shapes are
// nearly linearly dependent (see the recorded singular values), so other non-negative mixes
// reproduce them as well. What must hold is that the weights reproduce the shape.
class DefaultModels : public ::testing::TestWithParam<const char*> {};

TEST_P(DefaultModels, FullPosesAreReproducedAndTheirSeparationIsReported) {
  const auto path = default_model_path(GetParam());
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not built (target default_models)";
  const MorphableModel model = load_model_file(path);
  const VisemeSolver solver(model);
  const Eigen::MatrixXd directions = viseme_directions(model);
  const Eigen::VectorXd singular = Eigen::JacobiSVD<Eigen::MatrixXd>(directions).singularValues();
  std::string singular_list;
  for (const double s : singular) singular_list += std::to_string(s) + " ";
  RecordProperty("components", model.num_components());
  RecordProperty("viseme_singular_values_mm", singular_list);
  RecordProperty("condition_number", std::to_string(solver.condition_number()));
  if (singular.size() == kNumVisemes) EXPECT_NEAR(solver.condition_number() / (singular(0) / singular(kNumVisemes - 1)), 1.0, 1e-3);
  int one_hot = 0;
  for (int v = 0; v < kNumVisemes; ++v) {
    SCOPED_TRACE(kVisemeNames[v]);
    const VisemeWeights w = solver.solve(pose_alpha(model, *model.pose_index(std::string(kVisemeNames[v]) + "_100")));
    const Eigen::VectorXd mix = directions * Eigen::Map<const Eigen::VectorXf>(w.data(), kNumVisemes).cast<double>();
    EXPECT_LT((mix - directions.col(v)).norm(), 1e-3 * directions.col(v).norm());
    one_hot += largest(w) == v && w[v] > 0.99f;
  }
  RecordProperty("full_poses_with_one_hot_weights", one_hot);
}

INSTANTIATE_TEST_SUITE_P(Default, DefaultModels, ::testing::Values("default.lpm", "default17.lpm"),
                         [](const auto& info) { return std::string(info.param == std::string("default.lpm") ? "Poses161" : "Poses17"); });

TEST(VisemeSolver, NeedsNeutralAndEveryFullViseme) {
  MorphableModel model = testing::random_model(100, 20, 1);
  model.pose_names = {"neutral"};
  model.pose_coefficients = Eigen::MatrixXf::Zero(20, 1);
  EXPECT_THROW(VisemeSolver{model}, std::invalid_argument);
  for (std::string_view name : kVisemeNames) model.pose_names.emplace_back(name);  // the 17-pose naming
  model.pose_coefficients = Eigen::MatrixXf::Random(20, 17);
  EXPECT_NO_THROW(VisemeSolver{model});
  model.pose_names[0] = "rest";
  EXPECT_THROW(VisemeSolver{model}, std::invalid_argument);
}

TEST(VisemeSolver, SolveAllocatesNothing) {
  const VisemeSolver solver(random_viseme_model(2));
  const VisemeSolver::Coefficients alpha = testing::random_coefficients(20, 3);
  test::count_allocations_on_this_thread(true);
  const long before = test::allocation_count();
  float sum = 0;
  for (int frame = 0; frame < 100; ++frame) sum += solver.solve(alpha)[frame % kNumVisemes];
  EXPECT_EQ(test::allocation_count() - before, 0);
  test::count_allocations_on_this_thread(false);
  EXPECT_TRUE(std::isfinite(sum));
}

Landmarks2D with_noise(Landmarks2D landmarks, double sigma_px, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, sigma_px);
  for (double& value : landmarks.reshaped()) value += gauss(rng);
  return landmarks;
}

// "<viseme>_<percent>" -> (viseme index, percent / 100).
std::pair<int, double> viseme_and_intensity(const std::string& pose) {
  const std::size_t cut = pose.rfind('_');
  const auto viseme = std::find(kVisemeNames.begin(), kVisemeNames.end(), pose.substr(0, cut));
  int percent = 0;
  std::from_chars(pose.data() + cut + 1, pose.data() + pose.size(), percent);
  return {static_cast<int>(viseme - kVisemeNames.begin()), percent / 100.0};
}

// Every pose of the default model projected through a plausible camera (80 px between the
// outer eye corners, slightly off-axis), 1 px landmark noise, fitted like the daemon does
// (F4, default settings, cold start): the pose's viseme must be the largest weight, with the
// pose's intensity.
TEST(VisemeWeights, RecoversTheDefaultModelPosesThroughANoisyFit) {
  const auto path = default_model_path("default.lpm");
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not built (target default_models)";
  const MorphableModel model = load_model_file(path);
  const Fitter fitter(model, kDefaultLandmarkSet);
  const VisemeSolver solver(model);
  const Eigen::Matrix<double, 3, kNumLandmarks> neutral = testing::model_landmarks(model, Eigen::VectorXd::Zero(1));
  const double eye_span_mm = (neutral.col(ibug::kRightEyeOuter) - neutral.col(ibug::kLeftEyeOuter)).norm();
  const Eigen::Matrix<double, 3, 4> camera = testing::test_camera(80.0 / eye_span_mm);

  int poses = 0, recovered = 0, right_viseme = 0;
  double sum_squared_intensity_error = 0, worst_intensity_error = 0;
  std::map<std::pair<std::string_view, std::string_view>, int> confusions;  // (truth, largest) -> poses
  for (int pose = 0; pose < model.num_poses(); ++pose) {
    if (model.pose_names[pose] == "neutral") continue;
    const auto [viseme, intensity] = viseme_and_intensity(model.pose_names[pose]);
    ASSERT_LT(viseme, kNumVisemes) << model.pose_names[pose];
    const Landmarks2D truth = testing::project(camera, testing::model_landmarks(model, pose_alpha(model, pose)));
    FitOutput fit = Fitter::initial_output();
    fitter.fit(with_noise(truth, 1.0, 100 + pose), fit);
    const VisemeWeights w = solver.solve(fit.coefficients);
    const double intensity_error = std::abs(w[viseme] - intensity);
    ++poses;
    sum_squared_intensity_error += intensity_error * intensity_error;
    worst_intensity_error = std::max(worst_intensity_error, intensity_error);
    if (largest(w) == viseme) ++right_viseme;
    else ++confusions[{kVisemeNames[viseme], kVisemeNames[largest(w)]}];
    if (largest(w) == viseme && intensity_error <= 0.15) ++recovered;
  }
  const double recovery_rate = static_cast<double>(recovered) / poses;
  const double viseme_rate = static_cast<double>(right_viseme) / poses;
  const double rms_intensity_error = std::sqrt(sum_squared_intensity_error / poses);
  std::string confusion_list;
  for (const auto& [pair, count] : confusions)
    confusion_list += std::string(pair.first) + "->" + std::string(pair.second) + " x" + std::to_string(count) + "; ";
  RecordProperty("recovery_rate", std::to_string(recovery_rate));
  RecordProperty("largest_weight_rate", std::to_string(viseme_rate));
  RecordProperty("rms_intensity_error", std::to_string(rms_intensity_error));
  RecordProperty("worst_intensity_error", std::to_string(worst_intensity_error));
  RecordProperty("confusions", confusion_list);
  RecordProperty("condition_number", std::to_string(solver.condition_number()));
  EXPECT_GE(recovery_rate, 0.9) << "largest weight right in " << right_viseme << "/" << poses
                                << ", with intensity within 0.15 in " << recovered << "/" << poses
                                << "; RMS intensity error " << rms_intensity_error << "; confusions (truth->largest): "
                                << confusion_list;
}

}  // namespace
}  // namespace lipdrive
