// The 1€ filter (core/one_euro_filter) and the facial indices with the performer <-> model
// compatibility check (core/facial_indices, docs/method.md 6).
#include "build_paths.hpp"
#include "core/facial_indices.hpp"
#include "core/one_euro_filter.hpp"
#include "firmware_app/config/model_files.hpp"
#include "fixture_paths.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <random>
#include <stdexcept>

namespace lipdrive {
namespace {

constexpr double kFrameS = 1.0 / 60;

TEST(OneEuroFilter, ConstantInputStaysConstant) {
  OneEuroFilter filter({.min_cutoff_hz = 1.0, .beta = 0.5, .d_cutoff_hz = 1.0});
  for (int frame = 0; frame < 300; ++frame) EXPECT_DOUBLE_EQ(filter.filter(0.37, frame * kFrameS), 0.37);
}

int frames_to_reach_90_percent_of_a_step(double beta) {
  OneEuroFilter filter({.min_cutoff_hz = 1.0, .beta = beta, .d_cutoff_hz = 1.0});
  filter.filter(0.0, 0.0);
  for (int frame = 1; frame < 1000; ++frame)
    if (filter.filter(1.0, frame * kFrameS) >= 0.9) return frame;
  return 1000;
}

TEST(OneEuroFilter, FollowsAStepFasterWithSpeedCoefficient) {
  // beta = 0 is a plain exponential low-pass at 1 Hz: α = 1 / (1 + 60 / 2π) = 0.0948 per
  // frame, 90 % after ceil(ln 0.1 / ln(1 - α)) = 24 frames.
  EXPECT_EQ(frames_to_reach_90_percent_of_a_step(0.0), 24);
  const int adaptive = frames_to_reach_90_percent_of_a_step(1.0);
  RecordProperty("step_frames_beta_1", std::to_string(adaptive));
  EXPECT_LE(adaptive, 6);
}

TEST(OneEuroFilter, ReducesNoiseOnAStillSignal) {
  OneEuroFilter filter({.min_cutoff_hz = 1.0, .beta = 0.05, .d_cutoff_hz = 1.0});
  std::mt19937 rng(1);
  std::normal_distribution<double> noise(0.0, 0.02);
  double sum_squares = 0;
  int count = 0;
  for (int frame = 0; frame < 1200; ++frame) {
    const double out = filter.filter(0.5 + noise(rng), frame * kFrameS);
    if (frame >= 120) {  // after the first sample's error has decayed
      sum_squares += (out - 0.5) * (out - 0.5);
      ++count;
    }
  }
  const double out_std = std::sqrt(sum_squares / count);
  RecordProperty("still_noise_std_ratio", std::to_string(out_std / 0.02));
  // A 1 Hz low-pass at 60 fps passes sqrt(α / (2 − α)) = 0.22 of white noise; the speed
  // term may open it a little.
  EXPECT_LT(out_std, 0.35 * 0.02);
}

double lag_on_a_ramp(double beta) {
  OneEuroFilter filter({.min_cutoff_hz = 1.0, .beta = beta, .d_cutoff_hz = 1.0});
  double out = 0;
  int frame = 0;
  for (; frame <= 600; ++frame) out = filter.filter(0.5 * frame * kFrameS, frame * kFrameS);  // 0.5 per second
  return 0.5 * (frame - 1) * kFrameS - out;
}

TEST(OneEuroFilter, LargerSpeedCoefficientLagsLessOnARamp) {
  // beta = 0: a first-order low-pass lags a ramp of rate r by r·τ = 0.5 / 2π once settled.
  EXPECT_NEAR(lag_on_a_ramp(0.0), 0.5 / (2 * std::numbers::pi), 1e-9);
  const double lag_1 = lag_on_a_ramp(1.0), lag_10 = lag_on_a_ramp(10.0);
  RecordProperty("ramp_lag_beta_1", std::to_string(lag_1));
  RecordProperty("ramp_lag_beta_10", std::to_string(lag_10));
  EXPECT_LT(lag_1, lag_on_a_ramp(0.0));
  EXPECT_LT(lag_10, lag_1);
  EXPECT_GT(lag_10, 0);
}

TEST(OneEuroFilter, ResetPassesTheNextSampleThrough) {
  OneEuroFilter filter;
  filter.filter(0.0, 0.0);
  EXPECT_LT(filter.filter(1.0, kFrameS), 0.5);
  filter.reset();
  EXPECT_DOUBLE_EQ(filter.filter(1.0, 5.0), 1.0);
  EXPECT_DOUBLE_EQ(filter.filter(1.0, 5.0 + kFrameS), 1.0);
}

TEST(OneEuroFilter, ElapsedTimeSetsTheSmoothing) {
  // A frame that comes after a gap moves further than one after a frame period...
  OneEuroFilter regular, late;
  regular.filter(0.0, 0.0);
  late.filter(0.0, 0.0);
  EXPECT_GT(late.filter(1.0, 10 * kFrameS), regular.filter(1.0, kFrameS));
  // ... and a sample that is not later than the last one leaves the output alone.
  EXPECT_DOUBLE_EQ(late.filter(100.0, 10 * kFrameS), late.filter(-5.0, 9 * kFrameS));
  EXPECT_DOUBLE_EQ(low_pass_alpha(1.0, 1 / (2 * std::numbers::pi)), 0.5);  // dt = τ
}

TEST(OneEuroFilter, RejectsSettingsOutOfRange) {
  EXPECT_THROW(OneEuroFilter({.min_cutoff_hz = 0.0}), std::invalid_argument);
  EXPECT_THROW(OneEuroFilter({.beta = -1.0}), std::invalid_argument);
  EXPECT_THROW(OneEuroFilter({.d_cutoff_hz = -1.0}), std::invalid_argument);
}

// A frontal face in image pixels (y down) with n-gn = 120, zy-zy = 130, ex-ex = 90, and the
// lips set so that ls-li = lip_height and ch-ch = mouth_width.
Landmarks2D hand_made_face(double lip_height, double mouth_width) {
  Landmarks2D p = Landmarks2D::Zero();
  p.col(27) << 0, 0;    // n
  p.col(8) << 0, 120;   // gn
  p.col(0) << -65, 30;  // zy
  p.col(16) << 65, 30;
  p.col(4) << -50, 90;  // go
  p.col(12) << 50, 90;
  p.col(33) << 0, 50;    // sn
  p.col(31) << -17, 48;  // al
  p.col(35) << 17, 48;
  p.col(36) << -45, 10;  // ex
  p.col(45) << 45, 10;
  p.col(39) << -15, 10;  // en
  p.col(42) << 15, 10;
  p.col(51) << 0, 65;  // ls
  p.col(57) << 0, 65 + lip_height;
  p.col(48) << -mouth_width / 2, 72;  // ch
  p.col(54) << mouth_width / 2, 72;
  return p;
}

TEST(FacialIndices, HandComputedDistancesAndIndices) {
  const FacialMeasures m = facial_measures(hand_made_face(18, 45));
  EXPECT_DOUBLE_EQ(m.distances[0], 120);                                     // n-gn
  EXPECT_DOUBLE_EQ(m.distances[1], 130);                                     // zy-zy
  EXPECT_DOUBLE_EQ(m.distances[9], 45);                                      // ch-ch
  EXPECT_DOUBLE_EQ(m.distances[12], 120 - 83);                               // li-gn
  EXPECT_DOUBLE_EQ(m.indices[0], 100 * 120.0 / 130);                         // facial
  EXPECT_DOUBLE_EQ(m.indices[kVerticalMouthHeightIndex], 100 * 18.0 / 120);  // 15: middle
  EXPECT_DOUBLE_EQ(m.indices[kMouthWidthIndex], 100 * 45.0 / 90);            // 50: middle
  EXPECT_DOUBLE_EQ(m.indices[4], 100 * 34.0 / 50);                           // nasal: al-al / n-sn
  for (int i = 0; i < kNumFacialIndices; ++i)
    EXPECT_LT(m.indices[i], 100) << kFacialIndices[i].name << ": smaller / larger";
}

TEST(FacialIndices, ClassesOfTheMouthIndices) {
  // Vertical mouth height 100·ls-li/120: 12 (low), 15 (middle), 18 (high); mouth width
  // 100·ch-ch/90: 45 (low), 52 (middle), 58 (high).
  const struct {
    double lip_height, mouth_width;
    IndexClass height, width;
  } cases[] = {{14.4, 40.5, IndexClass::kLow, IndexClass::kLow},
               {18.0, 46.8, IndexClass::kMiddle, IndexClass::kMiddle},
               {21.6, 52.2, IndexClass::kHigh, IndexClass::kHigh},
               {14.4, 52.2, IndexClass::kLow, IndexClass::kHigh}};
  for (const auto& c : cases) {
    SCOPED_TRACE(::testing::Message() << c.lip_height << ", " << c.mouth_width);
    const MouthClasses classes = mouth_classes(facial_measures(hand_made_face(c.lip_height, c.mouth_width)));
    EXPECT_EQ(classes.vertical_mouth_height, c.height);
    EXPECT_EQ(classes.mouth_width, c.width);
  }
  // The thresholds belong to the middle class (low < 13.58 <= middle <= 16.22 < high).
  EXPECT_EQ(classify(13.58, kVerticalMouthHeightClasses), IndexClass::kMiddle);
  EXPECT_EQ(classify(16.22, kVerticalMouthHeightClasses), IndexClass::kMiddle);
  EXPECT_EQ(classify(13.5799, kVerticalMouthHeightClasses), IndexClass::kLow);
  EXPECT_EQ(classify(16.2201, kVerticalMouthHeightClasses), IndexClass::kHigh);
  EXPECT_EQ(classify(49.18, kMouthWidthClasses), IndexClass::kMiddle);
  EXPECT_EQ(classify(54.81, kMouthWidthClasses), IndexClass::kHigh);
}

TEST(FacialIndices, WarnsOnlyWhenVerticalMouthHeightIsTwoClassesApart) {
  const FacialMeasures low = facial_measures(hand_made_face(14.4, 46.8));
  const FacialMeasures middle = facial_measures(hand_made_face(18.0, 46.8));
  const FacialMeasures high = facial_measures(hand_made_face(21.6, 46.8));
  EXPECT_TRUE(compatibility(low, high).warn);
  EXPECT_TRUE(compatibility(high, low).warn);
  EXPECT_FALSE(compatibility(low, middle).warn);
  EXPECT_FALSE(compatibility(middle, high).warn);
  EXPECT_FALSE(compatibility(high, high).warn);
  // Mouth width two classes apart is reported, not warned about.
  const Compatibility widths =
      compatibility(facial_measures(hand_made_face(18.0, 40.5)), facial_measures(hand_made_face(18.0, 52.2)));
  EXPECT_FALSE(widths.warn);
  EXPECT_EQ(widths.performer.mouth_width, IndexClass::kLow);
  EXPECT_EQ(widths.model.mouth_width, IndexClass::kHigh);
}

TEST(FacialIndices, DefaultModelNeutralPose) {
  const auto path = std::filesystem::path(test::kModelDir) / "default.lpm";
  LIPDRIVE_REQUIRE_BUILT(path);
  const FacialMeasures m = facial_measures(frontal_neutral_landmarks(load_model_file(path)));
  const MouthClasses classes = mouth_classes(m);
  for (int i = 0; i < kNumFacialIndices; ++i) {
    RecordProperty(std::string(kFacialIndices[i].name), std::to_string(m.indices[i]));
    EXPECT_GT(m.indices[i], 0) << kFacialIndices[i].name;
    EXPECT_LT(m.indices[i], 100) << kFacialIndices[i].name << ": the smaller distance must be the smaller one";
  }
  RecordProperty("vertical_mouth_height_class", std::string(index_class_name(classes.vertical_mouth_height)));
  RecordProperty("mouth_width_class", std::string(index_class_name(classes.mouth_width)));
  // The model is a face with closed lips at rest: its vertical mouth height is a few
  // percent of its face height and its mouth about half its eye span.
  EXPECT_GT(m.indices[kVerticalMouthHeightIndex], 5);
  EXPECT_GT(m.indices[kMouthWidthIndex], 30);
}

TEST(FacialIndices, UnmappedModelLandmarkThrows) {
  MorphableModel model;
  model.mean = Eigen::VectorXf::Zero(3 * kNumLandmarks);
  for (int i = 0; i < kNumLandmarks; ++i) model.landmark_vertex[i] = i;
  EXPECT_NO_THROW(frontal_neutral_landmarks(model));
  model.landmark_vertex[51] = -1;
  EXPECT_THROW(frontal_neutral_landmarks(model), std::invalid_argument);
}

}  // namespace
}  // namespace lipdrive
