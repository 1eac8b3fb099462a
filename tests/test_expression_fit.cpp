// The fit of a model with expression shapes (core/fitting.hpp) on the ICT head: expression
// weights from synthetic frames of a random identity, the identity from noisy neutral frames,
// the bounds, no allocation per frame, the fit's weights under Apple's ARKit names, and the
// identity the daemon's processor fits of its own. Figures are printed and recorded as properties.
#include "allocation_counter.hpp"
#include "build_paths.hpp"
#include "core/arkit.hpp"
#include "core/drive_signals.hpp"
#include "core/fitting.hpp"
#include "core/morphable_model.hpp"
#include "core/mouth_measures.hpp"
#include "core/statistics.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "fixture_paths.hpp"
#include "reference_fitter.hpp"
#include "shared_predictor.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace lipdrive {
namespace {

const MorphableModel& ict_model() {
  static const MorphableModel model = load_model_file(std::filesystem::path(test::kModelDir) / "ict_face_light.lpm");
  return model;
}

Eigen::VectorXf random_identity(const MorphableModel& model, std::mt19937& rng) {
  std::normal_distribution<float> normal(0.f, 1.f);
  Eigen::VectorXf identity(model.num_components());
  for (float& a : identity) a = normal(rng);
  return identity;
}

/// The 68 landmarks (mm) of identity alpha and expression weights w.
Eigen::Matrix<double, 3, kNumLandmarks> ict_landmarks(const MorphableModel& model, const Eigen::VectorXf& identity,
                                                      const FitOutput::Expressions& w) {
  const Eigen::VectorXf shape = model.mean + model.basis * model.stddev.cwiseProduct(identity) +
                                model.expressions * w.head(model.num_expressions()).cast<float>();
  Eigen::Matrix<double, 3, kNumLandmarks> points;
  for (int i = 0; i < kNumLandmarks; ++i) points.col(i) = shape.segment<3>(3 * model.landmark_vertex[i]).cast<double>();
  return points;
}

/// The rig's view: 225 px between the outer eye corners (a head-mounted camera at 640x480).
Eigen::Matrix<double, 3, 4> rig_camera(const MorphableModel& model) {
  const auto neutral =
      ict_landmarks(model, Eigen::VectorXf::Zero(model.num_components()), FitOutput::Expressions::Zero());
  return testing::test_camera(225.0 / (neutral.col(ibug::kRightEyeOuter) - neutral.col(ibug::kLeftEyeOuter)).norm());
}

bool is_mouth(const std::string& name) { return name.starts_with("mouth") || name.starts_with("jaw"); }

/// Random expression: each observable shape active with probability 0.25 at a weight in
/// [0, 1]; mouthClose no more than jawOpen (ARKit's definition).
FitOutput::Expressions random_expression(const MorphableModel& model, std::mt19937& rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  FitOutput::Expressions w = FitOutput::Expressions::Zero();
  for (int e = 0; e < model.num_expressions(); ++e)
    if (!is_unobservable_expression(model.expression_names[e]) && uniform(rng) < 0.25) w[e] = uniform(rng);
  const int jaw = *model.expression_index("jawOpen"), close = *model.expression_index("mouthClose");
  w[close] = std::min(w[close], w[jaw]);
  return w;
}

Landmarks2D noisy(Landmarks2D landmarks, double sigma_px, std::mt19937& rng) {
  std::normal_distribution<double> noise(0.0, sigma_px);
  for (double& value : landmarks.reshaped()) value += noise(rng);
  return landmarks;
}

using MouthErrors = std::vector<std::pair<std::string, double>>;

/// Per mouth weight, the RMS error of random expressions on random identities, each held for
/// 10 frames (the fit warm-started frame to frame, as on video) with 1 px landmark noise.
MouthErrors mouth_weight_errors(LandmarkSet set, const FitSettings& settings) {
  const MorphableModel& model = ict_model();
  std::mt19937 rng(18);
  const Eigen::Matrix<double, 3, 4> camera = rig_camera(model);
  constexpr int kExpressions = 1200, kHeldFrames = 10;
  Eigen::ArrayXd squared_error = Eigen::ArrayXd::Zero(model.num_expressions());
  for (int sample = 0; sample < kExpressions; ++sample) {
    const Eigen::VectorXf identity = random_identity(model, rng);
    const Fitter fitter(model, set, settings, identity);
    const FitOutput::Expressions truth = random_expression(model, rng);
    const Landmarks2D seen = testing::project(camera, ict_landmarks(model, identity, truth));
    FitOutput fit = Fitter::initial_output();
    for (int frame = 0; frame < kHeldFrames; ++frame) fitter.fit(noisy(seen, 1.0, rng), fit);
    for (int e = 0; e < model.num_expressions(); ++e) {
      EXPECT_GE(fit.expressions[e], 0.0);
      EXPECT_LE(fit.expressions[e], 1.0);
      if (is_unobservable_expression(model.expression_names[e])) {
        EXPECT_EQ(fit.expressions[e], 0.0);
      }
      squared_error[e] += std::pow(fit.expressions[e] - truth[e], 2);
    }
  }
  MouthErrors errors;
  for (int e = 0; e < model.num_expressions(); ++e)
    if (is_mouth(model.expression_names[e]))
      errors.emplace_back(model.expression_names[e], std::sqrt(squared_error[e] / kExpressions));
  return errors;
}

/// mouth_weight_errors of the default fit, fitted once per set for the tests that read them.
const MouthErrors& default_mouth_weight_errors(LandmarkSet set) {
  static std::map<LandmarkSet, MouthErrors> errors;
  auto found = errors.find(set);
  if (found == errors.end()) found = errors.emplace(set, mouth_weight_errors(set, {})).first;
  return found->second;
}

TEST(ExpressionFit, RecoversRandomMouthWeightsOnARandomIdentity) {
  double jaw_open[2] = {0, 0};
  for (const LandmarkSet set : {LandmarkSet::F4, LandmarkSet::F5}) {
    int within = 0;
    std::string figures;
    for (const auto& [name, rms] : default_mouth_weight_errors(set)) {
      within += rms <= 0.1;
      figures += fmt::format(" {} {:.3f}", name, rms);
      ::testing::Test::RecordProperty(fmt::format("rms_{}_{}", landmark_set_name(set), name),
                                      fmt::format("{:.4f}", rms));
      if (name == "jawOpen") jaw_open[set == LandmarkSet::F5] = rms;
      // The target (issue: each mouth weight within RMS 0.1), with the jaw line.
      if (set == LandmarkSet::F5) {
        EXPECT_LE(rms, 0.1) << name;
      }
    }
    fmt::print("{}: mouth weights, RMS error (target <= 0.1 each):{}\n{}: {} within 0.1\n", landmark_set_name(set),
               figures, landmark_set_name(set), within);
  }
  // The jaw line (F5) is what shows the jaw: without it jawOpen is not recovered.
  EXPECT_LT(jaw_open[1], jaw_open[0]);
  // The camera <-> expression alternation converges within a frame's fit: 0.034 with the default
  // 10 alternations, 0.095 with 3, where the camera's scale and pitch kept part of the jaw's
  // motion (docs/arkit.md, "The alternation must converge").
  EXPECT_LT(jaw_open[1], 0.05);
}

// The sparse prior is what brings the weights a landmark moves less than 1 px under 0.1: with the
// ridge alone (the prior before it) the same expressions come back worse, the frowns, the lower
// lip and the pressed lips worst (docs/arkit.md, "A sparse prior").
TEST(ExpressionFit, TheSparsePriorRecoversMouthWeightsBetterThanTheRidgeAlone) {
  FitSettings ridge_only;
  ridge_only.expression_prior = 1.0;
  ridge_only.expression_sparsity = 0.0;
  const MouthErrors& sparse = default_mouth_weight_errors(LandmarkSet::F5);
  const MouthErrors ridge = mouth_weight_errors(LandmarkSet::F5, ridge_only);
  double sparse_worst = 0, ridge_worst = 0, sparse_sum = 0, ridge_sum = 0;
  for (std::size_t i = 0; i < sparse.size(); ++i) {
    sparse_worst = std::max(sparse_worst, sparse[i].second);
    ridge_worst = std::max(ridge_worst, ridge[i].second);
    sparse_sum += sparse[i].second * sparse[i].second;
    ridge_sum += ridge[i].second * ridge[i].second;
  }
  fmt::print("mouth weights, worst / RMS over the 27: sparse prior {:.3f} / {:.3f}, ridge alone {:.3f} / {:.3f}\n",
             sparse_worst, std::sqrt(sparse_sum / sparse.size()), ridge_worst, std::sqrt(ridge_sum / ridge.size()));
  EXPECT_LT(sparse_worst, ridge_worst);
  EXPECT_LT(sparse_sum, ridge_sum);
}

// The daemon keeps the model on its landmark vertices (LoadedFiles): the identity, the rest
// point, every frame's fit and the mouth reference come out exactly as from the whole model.
TEST(ExpressionFit, TheModelOnItsLandmarkVerticesFitsAsTheWholeModel) {
  const MorphableModel& whole = ict_model();
  const MorphableModel trimmed = landmark_vertices_only(whole);
  EXPECT_LE(trimmed.num_vertices(), kNumLandmarks);
  EXPECT_TRUE(trimmed.triangles.empty());
  EXPECT_EQ(trimmed.num_components(), whole.num_components());
  EXPECT_EQ(trimmed.expression_names, whole.expression_names);
  std::mt19937 rng(68);
  const Eigen::VectorXf identity = random_identity(whole, rng);
  const Eigen::Matrix<double, 3, 4> camera = rig_camera(whole);
  std::vector<Landmarks2D> frames;
  for (int frame = 0; frame < 20; ++frame)
    frames.push_back(noisy(testing::project(camera, ict_landmarks(whole, identity, random_expression(whole, rng))),
                           1.0, rng));
  for (int i = 0; i < kNumLandmarks; ++i)
    if (whole.landmark_vertex[i] >= 0) {
      EXPECT_EQ(ict_landmarks(trimmed, identity, FitOutput::Expressions::Zero()).col(i),
                ict_landmarks(whole, identity, FitOutput::Expressions::Zero()).col(i))
          << "landmark " << i;
    }
  const Eigen::VectorXf alpha_whole = fit_identity(whole, LandmarkSet::F5, frames);
  const Eigen::VectorXf alpha_trimmed = fit_identity(trimmed, LandmarkSet::F5, frames);
  EXPECT_EQ(alpha_trimmed, alpha_whole);
  EXPECT_EQ(fit_rest_expression(trimmed, LandmarkSet::F5, frames, alpha_whole),
            fit_rest_expression(whole, LandmarkSet::F5, frames, alpha_whole));
  EXPECT_EQ(mouth_reference(trimmed, alpha_whole).neutral_upper_lip_z,
            mouth_reference(whole, alpha_whole).neutral_upper_lip_z);
  const Fitter fit_whole(whole, LandmarkSet::F5, {}, alpha_whole), fit_trimmed(trimmed, LandmarkSet::F5, {}, alpha_whole);
  FitOutput a = Fitter::initial_output(), b = Fitter::initial_output();
  for (const Landmarks2D& frame : frames) {
    fit_whole.fit(frame, a);
    fit_trimmed.fit(frame, b);
    ASSERT_EQ(b.expressions, a.expressions);
    ASSERT_EQ(b.camera, a.camera);
    ASSERT_EQ(b.reprojection_error_px, a.reprojection_error_px);
  }
}

TEST(ExpressionFit, IdentityFromThirtyNoisyNeutralFramesReproducesTheNeutralLandmarks) {
  const MorphableModel& model = ict_model();
  std::mt19937 rng(30);
  const Eigen::Matrix<double, 3, 4> camera = rig_camera(model);
  double worst = 0;
  for (int performer = 0; performer < 10; ++performer) {
    const Eigen::VectorXf identity = random_identity(model, rng);
    const auto neutral = ict_landmarks(model, identity, FitOutput::Expressions::Zero());
    std::vector<Landmarks2D> frames;
    for (int frame = 0; frame < 30; ++frame) {
      // The head moves a little between frames.
      const Eigen::Matrix<double, 3, 4> moved =
          testing::test_camera(camera.row(0).head<3>().norm(), 0.2 + 0.01 * (frame % 7), -0.1 + 0.01 * (frame % 5));
      frames.push_back(noisy(testing::project(moved, neutral), 1.0, rng));
    }
    const Eigen::VectorXf fitted = fit_identity(model, kDefaultLandmarkSet, frames);
    // The recovered neutral under its best affine camera against the true neutral seen by the
    // rig (no noise): an identity is known up to what a camera takes up (size, position).
    const auto recovered = ict_landmarks(model, fitted, FitOutput::Expressions::Zero());
    const Landmarks2D seen = testing::project(camera, neutral);
    const std::span<const int> set = landmark_indices(kDefaultLandmarkSet);
    Eigen::MatrixXd points(set.size(), 4), target(set.size(), 2);
    for (std::size_t i = 0; i < set.size(); ++i) {
      points.row(i) << recovered.col(set[i]).transpose(), 1.0;
      target.row(i) = seen.col(set[i]).transpose();
    }
    const Eigen::MatrixXd residual = points * points.colPivHouseholderQr().solve(target) - target;
    const double rms = std::sqrt(residual.squaredNorm() / set.size());
    worst = std::max(worst, rms);
  }
  fmt::print(
      "identity from 30 noisy neutral frames: worst of 10 performers {:.3f} px RMS over the F4 landmarks (target <= 1 "
      "px)\n",
      worst);
  ::testing::Test::RecordProperty("identity_worst_rms_px", fmt::format("{:.3f}", worst));
  EXPECT_LE(worst, 1.0);
}

// What no identity explains on a performer's face (the detector's bias, here a rest expression
// on every neutral frame that the identity's components cannot take up) reads as expression
// weights at rest; the rest point from the neutral frames brings them to 0 and keeps a
// movement from the rest.
TEST(ExpressionFit, RestPointFromNeutralFramesReadsZeroAtRest) {
  const MorphableModel& model = ict_model();
  std::mt19937 rng(27);
  const Eigen::Matrix<double, 3, 4> camera = rig_camera(model);
  const Eigen::VectorXf identity = random_identity(model, rng);
  FitOutput::Expressions bias = FitOutput::Expressions::Zero();
  bias[*model.expression_index("mouthFrown_L")] = 0.4;
  bias[*model.expression_index("mouthRollUpper")] = 0.5;
  bias[*model.expression_index("cheekSquint_R")] = 0.4;
  bias[*model.expression_index("jawOpen")] = 0.1;
  const Landmarks2D rest_seen = testing::project(camera, ict_landmarks(model, identity, bias));
  std::vector<Landmarks2D> neutral;
  for (int frame = 0; frame < 20; ++frame) neutral.push_back(noisy(rest_seen, 1.0, rng));
  const Eigen::VectorXf fitted = fit_identity(model, LandmarkSet::F5, neutral);
  const FitOutput::Expressions rest = fit_rest_expression(model, LandmarkSet::F5, neutral, fitted);
  EXPECT_EQ(rest[*model.expression_index("jawOpen")], 0.0) << "the opening keeps its rest at 0";
  EXPECT_EQ(rest[*model.expression_index("mouthClose")], 0.0);

  const Fitter fitter(model, LandmarkSet::F5, {}, fitted);
  // Rest frames, then the same face with mouthSmile_L at 0.6 on top, each held 30 frames.
  FitOutput::Expressions smile = bias;
  smile[*model.expression_index("mouthSmile_L")] = 0.6;
  const Landmarks2D smile_seen = testing::project(camera, ict_landmarks(model, identity, smile));
  // Per shape, the median over the held frames (as the GRID figures take the final silence's).
  FitOutput fit = Fitter::initial_output();
  const auto held_medians = [&](const Landmarks2D& seen, bool relative_to_rest) {
    std::vector<std::vector<double>> weights(static_cast<std::size_t>(model.num_expressions()));
    FitOutput::Expressions relative;
    for (int frame = 0; frame < 60; ++frame) {
      fitter.fit(noisy(seen, 1.0, rng), fit);
      above_rest(fit.expressions, rest, relative);
      if (frame >= 30)
        for (int e = 0; e < model.num_expressions(); ++e)
          weights[static_cast<std::size_t>(e)].push_back(relative_to_rest ? relative[e] : fit.expressions[e]);
    }
    FitOutput::Expressions medians = FitOutput::Expressions::Zero();
    for (int e = 0; e < model.num_expressions(); ++e) medians[e] = median(weights[static_cast<std::size_t>(e)]);
    return medians;
  };
  const FitOutput::Expressions raw = held_medians(rest_seen, false), relative = held_medians(rest_seen, true);
  double worst_raw = 0, worst_relative = 0;
  for (int e = 0; e < model.num_expressions(); ++e) {
    if (e == *model.expression_index("jawOpen") || e == *model.expression_index("mouthClose")) continue;
    worst_raw = std::max(worst_raw, raw[e]);
    worst_relative = std::max(worst_relative, relative[e]);
  }
  const double smiling = held_medians(smile_seen, true)[*model.expression_index("mouthSmile_L")];
  fmt::print(
      "rest point: largest weight at rest {:.3f} as fitted, {:.3f} above the rest; mouthSmile_L 0.6 reads {:.3f}\n",
      worst_raw, worst_relative, smiling);
  EXPECT_GT(worst_raw, 0.2) << "the bias reads as expression weights";
  EXPECT_LT(worst_relative, 0.1) << "above the rest point the face at rest reads 0";
  EXPECT_NEAR(smiling, 0.6, 0.15);
}

// The daemon, live, cannot look ahead: without a calibrated identity its processor fits the
// first tracked frame's identity at once (the provisional one, which carries the fit), holds
// every ARKit weight at 0 while it gathers [model] auto_identity_frames tracked frames, then fits
// the identity of them all and lets the weights go. (`lipdrive process` has the whole take and
// fits that identity before its first row: test_process.cpp.)
TEST(ExpressionFit, LiveTheArkitWeightsWaitForTheIdentityOfTheFirstFrames) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const auto ict = std::make_shared<const MorphableModel>(
      load_model_file(std::filesystem::path(test::kModelDir) / "ict_face_light.lpm"));
  constexpr int kIdentityFrames = 20;
  FrameProcessor processor(*ict, LandmarkSet::F5, FitSettings{}, test::shared_predictor(), Eigen::VectorXf(),
                           FitOutput::Expressions::Zero(), AutoIdentity{.model = ict, .frames = kIdentityFrames});
  ASSERT_TRUE(processor.identity_pending());
  EXPECT_EQ(processor.identity().size(), 0) << "the mean face before any frame";
  cv::VideoCapture capture(test::kClip.string());
  cv::Mat bgr, gray;
  int tracked = 0;
  float most_while_gathering = 0, most_after = 0;
  while (capture.read(bgr)) {
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
    const bool gathering = processor.identity_pending();
    ASSERT_TRUE(processor.process(gray, cv::Mat()).tracked) << "frame " << tracked;
    ++tracked;
    DriveSignals signals;
    processor.set_arkit(signals);
    float& most = gathering ? most_while_gathering : most_after;
    for (const float w : signals.arkit()) most = std::max(most, w);
    EXPECT_EQ(processor.identity_pending(), tracked < kIdentityFrames) << "after tracked frame " << tracked;
    if (tracked == 1) {
      EXPECT_EQ(processor.identity().size(), ict->num_components()) << "the provisional identity";
    }
  }
  ASSERT_GT(tracked, 2 * kIdentityFrames);
  EXPECT_EQ(most_while_gathering, 0);
  EXPECT_GT(most_after, 0.3) << "the weights move once the identity is fitted";
}

TEST(ExpressionFit, AboveRestMapsTheRestTo0AndAFullShapeTo1) {
  FitOutput::Expressions rest = FitOutput::Expressions::Zero(), w = FitOutput::Expressions::Zero(), out;
  rest[0] = 0.5, rest[1] = 0.5, rest[2] = 0.5, rest[3] = 0.0, rest[4] = 0.2;
  w[0] = 0.5, w[1] = 1.0, w[2] = 0.2, w[3] = 0.3, w[4] = 0.6;
  above_rest(w, rest, out);
  EXPECT_DOUBLE_EQ(out[0], 0.0);
  EXPECT_DOUBLE_EQ(out[1], 1.0);
  EXPECT_DOUBLE_EQ(out[2], 0.0) << "below the rest is the rest";
  EXPECT_DOUBLE_EQ(out[3], 0.3) << "a zero rest leaves the weight";
  EXPECT_DOUBLE_EQ(out[4], 0.5);
}

TEST(ExpressionFit, AllocatesNothingPerFrame) {
  const MorphableModel& model = ict_model();
  std::mt19937 rng(5);
  const Eigen::VectorXf identity = random_identity(model, rng);
  for (const LandmarkSet set : {LandmarkSet::F4, LandmarkSet::F5}) {
    const Fitter fitter(model, set, {}, identity);
    const Landmarks2D landmarks =
        testing::project(rig_camera(model), ict_landmarks(model, identity, random_expression(model, rng)));
    FitOutput output = Fitter::initial_output();
    test::count_allocations_on_this_thread(true);
    const long before = test::allocation_count();
    FitOutput::Expressions relative;
    for (int frame = 0; frame < 100; ++frame) {
      fitter.fit(landmarks, output);
      above_rest(output.expressions, output.expressions, relative);
    }
    EXPECT_EQ(test::allocation_count() - before, 0) << landmark_set_name(set);
    test::count_allocations_on_this_thread(false);
    EXPECT_LT(output.reprojection_error_px, 0.5) << "noise-free frames are explained";
  }
}

// Known expressions on a random identity, fitted (F5), come out under Apple's names with their
// weights (core/arkit.hpp). Without landmark noise (the recovery under noise is the test
// above), each held a second at 60 fps: from the mean face the camera and the shapes converge
// over tens of frames (jawOpen 0.5 reads 0.35 after 10 frames, 0.46 after 30, 0.49 after 60).
TEST(ExpressionFit, ArkitWeightsOfTheFitCarryApplesNames) {
  const MorphableModel& model = ict_model();
  const ArkitMap map(model.expression_names);
  std::mt19937 rng(52);
  const Eigen::VectorXf identity = random_identity(model, rng);
  const Fitter fitter(model, LandmarkSet::F5, {}, identity);
  const auto arkit_of = [&](const std::vector<std::pair<std::string, double>>& truth) {
    FitOutput::Expressions w = FitOutput::Expressions::Zero();
    for (const auto& [name, value] : truth) w[*model.expression_index(name)] = value;
    const Landmarks2D seen = testing::project(rig_camera(model), ict_landmarks(model, identity, w));
    FitOutput fit = Fitter::initial_output();
    for (int frame = 0; frame < 60; ++frame) fitter.fit(seen, fit);
    DriveSignals signals;
    set_arkit_signals(map, std::span<const double>(fit.expressions.data(), fit.expressions.size()), signals);
    // Each Apple name carries its shape's fitted weight, a split shape the mean of its halves.
    for (int a = 0; a < kNumArkit; ++a) {
      const auto [first, second] = map.sources(a);
      const double expected = first < 0    ? 0.0
                              : second < 0 ? fit.expressions[first]
                                           : (fit.expressions[first] + fit.expressions[second]) / 2;
      EXPECT_NEAR(signals[arkit_signal(a)], expected, 1e-6) << kArkitNames[static_cast<std::size_t>(a)];
    }
    return signals;
  };
  const auto weight = [](const DriveSignals& s, std::string_view name) { return s[arkit_signal(*arkit_index(name))]; };
  const DriveSignals jaw = arkit_of({{"jawOpen", 0.5}});
  EXPECT_NEAR(weight(jaw, "jawOpen"), 0.5, 0.1);
  const DriveSignals smile = arkit_of({{"mouthSmile_L", 0.7}});
  EXPECT_NEAR(weight(smile, "mouthSmileLeft"), 0.7, 0.1);
  EXPECT_LT(weight(smile, "mouthSmileRight"), 0.1) << "the other side";
  const DriveSignals pucker = arkit_of({{"mouthPucker", 0.7}});
  EXPECT_NEAR(weight(pucker, "mouthPucker"), 0.7, 0.1);
  const DriveSignals brows = arkit_of({{"browInnerUp_L", 0.6}, {"browInnerUp_R", 0.6}});
  EXPECT_NEAR(weight(brows, "browInnerUp"), 0.6, 0.1) << "the halves merged";
  for (const DriveSignals& s : {jaw, smile, pucker, brows})
    for (const char* held : {"cheekPuff", "tongueOut", "eyeLookUpLeft", "eyeLookOutRight"})
      EXPECT_EQ(weight(s, held), 0) << held;
}

TEST(ExpressionFit, RejectsASetWithoutEyesAndBrowsAndAWrongIdentitySize) {
  const MorphableModel& model = ict_model();
  EXPECT_THROW(Fitter(model, LandmarkSet::F1), std::invalid_argument);
  EXPECT_THROW(Fitter(model, LandmarkSet::F4, {}, Eigen::VectorXf::Zero(3)), std::invalid_argument);
  EXPECT_TRUE(Fitter(model, LandmarkSet::F4).fits_expressions());
}

}  // namespace
}  // namespace lipdrive
