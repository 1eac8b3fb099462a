// Mouth measures (docs/method.md 4) on hand-made landmarks with hand-computed answers.
#include "core/mouth_measures.hpp"

#include <gtest/gtest.h>

#include <array>

#include <cmath>
#include <stdexcept>

namespace lipdrive {
namespace {

// All landmarks at (100, 100) except those the measures read, placed so that
// d = |midpoint(p39, p42) - p30| = 40, W = |p60 - p64| = 30, H = |p62 - p66| = 10.
Landmarks2D hand_made_landmarks() {
  Landmarks2D p = Landmarks2D::Constant(100.0);
  p.col(39) << 80, 60;  // inner eye corners, midpoint (100, 60)
  p.col(42) << 120, 60;
  p.col(30) << 100, 100;  // nose tip: 40 below
  p.col(60) << 85, 130;   // inner lip corners: 30 apart
  p.col(64) << 115, 130;
  p.col(62) << 100, 125;  // inner lip middles: 10 apart
  p.col(66) << 100, 135;
  return p;
}

TEST(MouthRatios, HandComputedWidthAndHeightOverD) {
  const MouthRatios r = mouth_ratios<2>(hand_made_landmarks());
  EXPECT_DOUBLE_EQ(r.d, 40.0);
  EXPECT_DOUBLE_EQ(r.width, 30.0 / 40.0);
  EXPECT_DOUBLE_EQ(r.height, 10.0 / 40.0);
}

TEST(MouthRatios, ScaleAndRotationFree) {
  // A rotated, scaled, shifted copy of the face gives the same ratios.
  const double a = 0.3, s = 2.5;
  Eigen::Matrix2d turn;
  turn << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  const Landmarks2D moved = ((s * turn) * hand_made_landmarks()).colwise() + Eigen::Vector2d(7, -3);
  const MouthRatios r = mouth_ratios<2>(moved);
  EXPECT_NEAR(r.width, 0.75, 1e-12);
  EXPECT_NEAR(r.height, 0.25, 1e-12);
  EXPECT_NEAR(r.d, 100.0, 1e-12);
}

TEST(MouthRatios, ThreeDimensionalPointsUseTheirDepth) {
  Eigen::Matrix<double, 3, kNumLandmarks> p = Eigen::Matrix<double, 3, kNumLandmarks>::Zero();
  p.col(39) << -10, 30, 0;
  p.col(42) << 10, 30, 0;
  p.col(30) << 0, 0, 40;  // d = |(0, 30, 0) - (0, 0, 40)| = 50
  p.col(60) << -20, -20, 0;
  p.col(64) << 20, -20, 0;  // W = 40
  p.col(62) << 0, -15, 6;
  p.col(66) << 0, -15, -6;  // H = 12, along z only
  const MouthRatios r = mouth_ratios<3>(p);
  EXPECT_DOUBLE_EQ(r.d, 50.0);
  EXPECT_DOUBLE_EQ(r.width, 40.0 / 50.0);
  EXPECT_DOUBLE_EQ(r.height, 12.0 / 50.0);
}

// A model whose 68 vertices are the landmarks, with one component that pushes the upper-lip
// midpoint (51) forwards along z: pose "neutral" has alpha = 1, pose "pucker" alpha = 3.
MorphableModel protrusion_model(bool with_neutral) {
  MorphableModel m;
  m.mean = Eigen::VectorXf::Zero(3 * kNumLandmarks);
  m.stddev = Eigen::VectorXf::Constant(1, 2.0f);
  m.basis = Eigen::MatrixXf::Zero(3 * kNumLandmarks, 1);
  m.basis(3 * 51 + 2, 0) = 1.0f;  // z of vertex 51
  for (int i = 0; i < kNumLandmarks; ++i) m.landmark_vertex[i] = i;
  m.pose_names = with_neutral ? std::vector<std::string>{"pucker", "neutral"} : std::vector<std::string>{"pucker"};
  m.pose_coefficients = Eigen::MatrixXf(1, m.pose_names.size());
  m.pose_coefficients(0, 0) = 3.0f;
  if (with_neutral) m.pose_coefficients(0, 1) = 1.0f;
  return m;
}

TEST(MouthReference, NeutralPoseOrTheMean) {
  EXPECT_DOUBLE_EQ(mouth_reference(protrusion_model(true)).neutral_upper_lip_z, 2.0);  // mean 0 + 1 * stddev 2
  EXPECT_DOUBLE_EQ(mouth_reference(protrusion_model(false)).neutral_upper_lip_z, 0.0);
  // Every landmark the measures read from the model must be mapped: a lips-only model would
  // measure NaN widths and protrusions on every frame.
  for (const int landmark : {30, 39, 42, 51, 60, 62, 64, 66}) {
    MorphableModel unmapped = protrusion_model(true);
    unmapped.landmark_vertex[landmark] = -1;
    EXPECT_THROW(mouth_reference(unmapped), std::invalid_argument) << "landmark " << landmark;
  }
  MorphableModel jaw_unmapped = protrusion_model(true);
  jaw_unmapped.landmark_vertex[ibug::kChin] = -1;
  EXPECT_NO_THROW(mouth_reference(jaw_unmapped)) << "the measures do not read the jaw line";
}

// A model with expression shapes: the identity's shape moved by the rest point's weights.
TEST(MouthReference, TheIdentityAtItsRestPoint) {
  MorphableModel m = protrusion_model(false);
  m.expressions = Eigen::MatrixXf::Zero(3 * kNumLandmarks, 2);
  m.expressions(3 * 51 + 2, 1) = -4.0f;  // the second shape draws the upper lip in by 4 mm
  m.expression_names = {"mouthFunnel", "mouthRollUpper"};
  const Eigen::VectorXf identity = Eigen::VectorXf::Constant(1, 1.0f);
  EXPECT_DOUBLE_EQ(mouth_reference(m, identity).neutral_upper_lip_z, 2.0);
  const std::array<double, 3> rest{0.9, 0.5, 0.7};  // a fitter's size: the shapes past the model's are ignored
  EXPECT_DOUBLE_EQ(mouth_reference(m, identity, rest).neutral_upper_lip_z, 0.0);
}

TEST(MeasureMouth, AllMeasuresOfAFrame) {
  const MorphableModel model = protrusion_model(true);
  const MouthReference reference = mouth_reference(model);

  FitOutput fit = Fitter::initial_output();
  fit.projected = hand_made_landmarks();
  fit.projected(1, 66) = 145;  // the fit opens the mouth twice as far: H = 20
  // The model-space landmarks of the "pucker" pose, with d_3d = 50 and the lip points as above.
  const Eigen::VectorXf pucker = model.shape(model.pose_coefficients.col(0));
  fit.model_landmarks = Eigen::Map<const Eigen::Matrix3Xf>(pucker.data(), 3, kNumLandmarks).cast<double>();
  fit.model_landmarks.col(39) << -10, 30, 0;
  fit.model_landmarks.col(42) << 10, 30, 0;
  fit.model_landmarks.col(30) << 0, 0, 40;
  fit.model_landmarks.col(60) << -20, -20, 0;
  fit.model_landmarks.col(64) << 20, -20, 0;
  fit.reprojection_error_px = 6.0;  // 15 % of d = 40 px

  const MouthMeasures m = measure_mouth(hand_made_landmarks(), fit, reference);
  EXPECT_DOUBLE_EQ(m.width_2d, 0.75);
  EXPECT_DOUBLE_EQ(m.height_2d, 0.25);
  EXPECT_DOUBLE_EQ(m.width_fit, 0.75);
  EXPECT_DOUBLE_EQ(m.height_fit, 0.5);
  EXPECT_DOUBLE_EQ(m.width_3d, 40.0 / 50.0);
  EXPECT_DOUBLE_EQ(m.height_3d, 0.0);  // 62 and 66 coincide in this shape
  // z51 = 3 * 2 = 6 mm in "pucker", 2 mm in "neutral": (6 - 2) / 50.
  EXPECT_DOUBLE_EQ(m.protrusion_3d, 4.0 / 50.0);
  EXPECT_DOUBLE_EQ(m.quality, 0.5);
}

TEST(FitQuality, FallsWithRelativeError) {
  EXPECT_DOUBLE_EQ(fit_quality(0.0, 40.0), 1.0);
  EXPECT_DOUBLE_EQ(fit_quality(6.0, 40.0), 0.5);
  EXPECT_LT(fit_quality(20.0, 40.0), 0.1);
  EXPECT_GT(fit_quality(1.0, 40.0), fit_quality(1.0, 20.0));  // the same error on a smaller face is worse
  EXPECT_EQ(fit_quality(std::nan(""), 40.0), 0.0);
}

}  // namespace
}  // namespace lipdrive
