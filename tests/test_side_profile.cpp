// Upper-lip protrusion from the side camera (core/side_profile.hpp) on the built-in head
// rendered in profile (sim/side_view.hpp), whose 3D shape gives the truth; and on the
// generated fixture clip build/fixtures/side_view.avi with its truth CSV.
#include "allocation_counter.hpp"
#include "build_paths.hpp"
#include "core/metrics.hpp"
#include "core/side_profile.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "sim/side_view.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

const SyntheticHead& head161() {
  static const SyntheticHead head = generate_synthetic_head(HeadPoseSet::Full161);
  return head;
}

const HeadPose& pose(const std::string& name) {
  const auto& poses = head161().poses;
  const auto it = std::ranges::find(poses, name, &HeadPose::name);
  if (it == poses.end()) throw std::out_of_range("no pose " + name);
  return *it;
}

// One view of the head per facing; frames of it in grey, as the side camera delivers them.
struct Profile {
  ProfileFacing facing;
  SideViewOptions options;
  ImageProjection projection;

  explicit Profile(ProfileFacing f)
      : facing(f),
        options{{640, 480}, f == ProfileFacing::kRight ? 90.0f : -90.0f},
        projection(side_projection(head161(), options)) {}

  cv::Mat grey(const Eigen::Matrix3Xf& vertices) const {
    cv::Mat grey;
    cv::cvtColor(render_side_view(head161(), vertices, options.frame_size, projection), grey, cv::COLOR_BGR2GRAY);
    return grey;
  }
  cv::Mat grey(const std::string& name) const { return grey(pose(name).vertices); }
  SideProfileMeter meter() const {
    SideProfileSettings settings;
    settings.facing = facing;
    return SideProfileMeter(settings);
  }
};

const Profile& profile(ProfileFacing facing) {
  static const Profile right(ProfileFacing::kRight), left(ProfileFacing::kLeft);
  return facing == ProfileFacing::kRight ? right : left;
}

SideReference neutral_reference(SideProfileMeter& meter, const Profile& view) {
  const cv::Mat neutral = view.grey("neutral");
  return calibrate_side(meter, std::span(&neutral, 1));
}

cv::Mat translated(const cv::Mat& grey, double dx, double dy) {
  cv::Mat out;
  cv::warpAffine(grey, out, cv::Matx23d(1, 0, dx, 0, 1, dy), grey.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
                 cv::Scalar(0));
  return out;
}

std::vector<double> ranks(const std::vector<double>& values) {
  std::vector<std::size_t> order(values.size());
  std::iota(order.begin(), order.end(), 0);
  std::ranges::sort(order, {}, [&](std::size_t i) { return values[i]; });
  std::vector<double> rank(values.size());
  for (std::size_t i = 0; i < order.size();) {  // ties share their mean rank
    std::size_t j = i;
    while (j + 1 < order.size() && values[order[j + 1]] == values[order[i]]) ++j;
    for (std::size_t k = i; k <= j; ++k) rank[order[k]] = (i + j) / 2.0;
    i = j + 1;
  }
  return rank;
}

class SideProfileTest : public ::testing::TestWithParam<ProfileFacing> {
 protected:
  const Profile& view() const { return profile(GetParam()); }
};

TEST_P(SideProfileTest, FindsTheProfileLandmarksInOrder) {
  SideProfileMeter meter = view().meter();
  const SideProfile p = meter.find(view().grey("neutral"));
  ASSERT_TRUE(p.ok()) << static_cast<int>(p.status);
  // Top to bottom: root, tip, subnasale, upper lip; the tip is foremost.
  EXPECT_LT(p.nose_root.y, p.nose_tip.y);
  EXPECT_LT(p.nose_tip.y, p.subnasale.y);
  EXPECT_LT(p.subnasale.y, p.upper_lip.y);
  const float ahead = GetParam() == ProfileFacing::kRight ? 1.0f : -1.0f;
  for (const cv::Point2f& q : {p.nose_root, p.subnasale, p.upper_lip}) EXPECT_LT(ahead * q.x, ahead * p.nose_tip.x);

  // The tip and root are where the head's landmarks 30 and 27 project, and the nose
  // length is their distance in the image.
  const HeadPose& neutral = pose("neutral");
  const auto projected = [&](int landmark) {
    return view().projection.project(neutral.vertices.col(head161().landmark_vertex[landmark]));
  };
  const Eigen::Vector2f tip = projected(30), root = projected(27);
  const double scale = view().projection.scale;  // px per mm
  EXPECT_LT((Eigen::Vector2f(p.nose_tip.x, p.nose_tip.y) - tip).norm(), 3 * scale);
  EXPECT_LT((Eigen::Vector2f(p.nose_root.x, p.nose_root.y) - root).norm(), 6 * scale);
  EXPECT_NEAR(p.nose_length_px, (tip - root).norm(), 0.08 * (tip - root).norm());
}

TEST_P(SideProfileTest, NeutralMeasuresZeroAndRoundedVisemesPositive) {
  SideProfileMeter meter = view().meter();
  const SideReference reference = neutral_reference(meter, view());
  const SideMeasure neutral = meter.measure(view().grey("neutral"), reference);
  ASSERT_TRUE(neutral.ok());
  EXPECT_NEAR(neutral.protrusion, 0.0, 1e-9);

  for (const char* rounded : {"W_100", "Ooh-Q_100", "Oh_100", "W_050"}) {
    const SideMeasure m = meter.measure(view().grey(rounded), reference);
    const double truth = upper_lip_protrusion(head161(), pose(rounded).vertices);
    ASSERT_TRUE(m.ok()) << rounded;
    EXPECT_GT(m.protrusion, 0.04) << rounded;
    EXPECT_NEAR(m.protrusion, truth, 0.02) << rounded;
  }
  // Open, spread, pressed and tucked lips leave the upper lip's depth alone.
  for (const char* other : {"BigAah_100", "Eee_100", "B-M-P_100", "F-V_100"}) {
    const SideMeasure m = meter.measure(view().grey(other), reference);
    ASSERT_TRUE(m.ok()) << other;
    EXPECT_LT(std::abs(m.protrusion), 0.025) << other;
  }
}

TEST_P(SideProfileTest, RankingOfAllPosesFollowsTheTruth) {
  SideProfileMeter meter = view().meter();
  const SideReference reference = neutral_reference(meter, view());
  std::vector<double> truth, measured, moved_truth, moved_measured;
  for (const HeadPose& p : head161().poses) {
    const SideMeasure m = meter.measure(view().grey(p.vertices), reference);
    ASSERT_TRUE(m.ok()) << p.name;
    truth.push_back(upper_lip_protrusion(head161(), p.vertices));
    measured.push_back(m.protrusion);
    if (std::abs(truth.back()) < 1e-3) continue;  // ~100 poses leave the upper lip's depth alone: a tie
    moved_truth.push_back(truth.back());
    moved_measured.push_back(m.protrusion);
  }
  const SeriesAgreement agreement = compare_series(truth, measured);
  const double spearman = compare_series(ranks(moved_truth), ranks(moved_measured)).pearson_r;
  std::printf(
      "[ figures  ] %s facing, %zu poses: Pearson r %.4f, scaled RMSE %.4f, MAE %.4f; "
      "Spearman rho over the %zu that move the upper lip %.4f\n",
      GetParam() == ProfileFacing::kRight ? "right" : "left", truth.size(), agreement.pearson_r, agreement.rmse_scaled,
      agreement.mae, moved_truth.size(), spearman);
  EXPECT_GE(agreement.pearson_r, 0.9);
  EXPECT_GE(spearman, 0.9);
}

TEST_P(SideProfileTest, HeadShiftMovesTheMeasureLittle) {
  SideProfileMeter meter = view().meter();
  const SideReference reference = neutral_reference(meter, view());
  const cv::Mat rounded = view().grey("W_080");
  const double still = meter.measure(rounded, reference).protrusion;
  for (const auto& [dx, dy] : {std::pair{4.0, 0.0}, std::pair{-3.0, 5.0}, std::pair{1.5, -2.5}, std::pair{-0.5, 0.5}}) {
    const SideMeasure shifted = meter.measure(translated(rounded, dx, dy), reference);
    ASSERT_TRUE(shifted.ok()) << dx << "," << dy;
    EXPECT_NEAR(shifted.protrusion, still, 0.01) << dx << "," << dy;
    EXPECT_NEAR(shifted.profile.nose_tip.x, meter.find(rounded).nose_tip.x + dx, 1.0);
  }
}

TEST_P(SideProfileTest, AProfileWhoseNoseIsAnotherLengthIsNotTheCalibratedFace) {
  // The camera moves with the head, so the calibrated nose keeps its length in the picture.
  // The same profile larger about its nose tip (the camera slipped closer on the rig, or
  // another face in view) is a complete profile but not the calibrated one; a little larger
  // is within max_nose_change.
  SideProfileMeter meter = view().meter();
  const SideReference reference = neutral_reference(meter, view());
  const cv::Mat neutral = view().grey("neutral");
  const cv::Point2f tip = meter.find(neutral).nose_tip;
  for (const double scale : {1.1, 1.4}) {
    cv::Mat larger;
    cv::warpAffine(neutral, larger, cv::Matx23d(scale, 0, (1 - scale) * tip.x, 0, scale, (1 - scale) * tip.y),
                   neutral.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    ASSERT_TRUE(meter.find(larger).ok()) << scale;
    const SideMeasure m = meter.measure(larger, reference);
    if (scale - 1 < meter.settings().max_nose_change) {
      EXPECT_TRUE(m.ok()) << scale;
    } else {
      EXPECT_EQ(m.profile.status, SideStatus::kNotTheFace) << scale;
      EXPECT_TRUE(std::isnan(m.protrusion)) << scale;
    }
  }
}

TEST_P(SideProfileTest, ACropAroundTheLowerFaceMeasuresTheSame) {
  SideProfileMeter full = view().meter();
  const SideReference full_reference = neutral_reference(full, view());
  const SideProfile whole = full.find(view().grey("neutral"));
  // From the brow (40 mm above the nose root) to the bottom of the frame, 40 px of
  // background in front of the nose tip and 150 px of face behind it.
  const bool right = GetParam() == ProfileFacing::kRight;
  const int front = cvRound(whole.nose_tip.x) + (right ? 40 : -40);
  const int back = cvRound(whole.nose_tip.x) + (right ? -150 : 150);
  const int top = cvRound(whole.nose_root.y - 40 * view().projection.scale);
  SideProfileSettings settings = full.settings();
  settings.crop = cv::Rect(std::min(front, back), top, 190, 480 - top);
  SideProfileMeter cropped(settings);
  const SideReference reference = neutral_reference(cropped, view());
  EXPECT_NEAR(reference.nose_length_px, full_reference.nose_length_px, 0.05 * full_reference.nose_length_px);
  for (const char* name : {"W_100", "Ooh-Q_050", "BigAah_100"}) {
    const SideMeasure m = cropped.measure(view().grey(name), reference);
    ASSERT_TRUE(m.ok()) << name;
    EXPECT_NEAR(m.protrusion, full.measure(view().grey(name), full_reference).protrusion, 0.01) << name;
    // Reported in frame pixels; Otsu's level on the smaller crop moves the outline by a pixel or two.
    EXPECT_NEAR(m.profile.nose_tip.x, whole.nose_tip.x, 3.0) << name;
  }
}

TEST_P(SideProfileTest, SkinDarkerThanTheBackgroundMeasuresTheSame) {
  SideProfileMeter meter = view().meter();
  const SideReference reference = neutral_reference(meter, view());
  const auto inverted = [](const cv::Mat& grey) { return cv::Mat(255 - grey); };
  const cv::Mat neutral = inverted(view().grey("neutral"));
  const SideReference inverted_reference = calibrate_side(meter, std::span(&neutral, 1));
  EXPECT_NEAR(inverted_reference.nose_length_px, reference.nose_length_px, 0.03 * reference.nose_length_px);
  for (const char* name : {"W_100", "Oh_060", "BigAah_100"}) {
    const SideMeasure dark = meter.measure(inverted(view().grey(name)), inverted_reference);
    ASSERT_TRUE(dark.ok()) << name;
    EXPECT_NEAR(dark.protrusion, meter.measure(view().grey(name), reference).protrusion, 0.01) << name;
  }
}

TEST_P(SideProfileTest, AllocatesNothingPerFrameAfterTheFirst) {
  SideProfileMeter meter = view().meter();
  const SideReference reference = neutral_reference(meter, view());
  const std::vector<cv::Mat> frames{view().grey("W_100"), view().grey("BigAah_100"), cv::Mat(480, 640, CV_8UC1, 0.0)};
  test::count_allocations_on_this_thread(true);
  const long before = test::allocation_count();
  double sum = 0;
  for (const cv::Mat& frame : frames) sum += meter.measure(frame, reference).profile.nose_length_px;
  const long allocations = test::allocation_count() - before;
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(sum, 0);
}

INSTANTIATE_TEST_SUITE_P(Facing, SideProfileTest, ::testing::Values(ProfileFacing::kRight, ProfileFacing::kLeft),
                         [](const auto& info) { return info.param == ProfileFacing::kRight ? "Right" : "Left"; });

TEST(SideProfile, NoSilhouetteOnBlankFrames) {
  SideProfileMeter meter;
  EXPECT_EQ(meter.find(cv::Mat(480, 640, CV_8UC1, 0.0)).status, SideStatus::kNoSilhouette);
  EXPECT_EQ(meter.find(cv::Mat(480, 640, CV_8UC1, 128.0)).status, SideStatus::kNoSilhouette);
  cv::Mat faint(480, 640, CV_8UC1);  // sensor noise only
  cv::randn(faint, 40, 3);
  EXPECT_EQ(meter.find(faint).status, SideStatus::kNoSilhouette);
  EXPECT_FALSE(meter.measure(faint, {}).ok());
  EXPECT_TRUE(std::isnan(meter.measure(faint, {}).protrusion));
}

TEST(SideProfile, EmptyFrameOrCropIsReported) {
  EXPECT_EQ(SideProfileMeter().find(cv::Mat()).status, SideStatus::kEmptyCrop);
  SideProfileSettings off_frame_crop;
  off_frame_crop.crop = cv::Rect(700, 0, 50, 50);
  SideProfileMeter off_frame(off_frame_crop);
  EXPECT_EQ(off_frame.find(profile(ProfileFacing::kRight).grey("neutral")).status, SideStatus::kEmptyCrop);
  EXPECT_THROW(SideProfileMeter().find(cv::Mat(10, 10, CV_8UC3)), std::invalid_argument);
}

TEST(SideProfile, ShapesWithoutAFaceAreRejected) {
  SideProfileMeter meter;
  cv::Mat disk(480, 640, CV_8UC1, 0.0);  // convex: no nose root above its foremost point
  cv::circle(disk, {320, 240}, 150, cv::Scalar(180), cv::FILLED);
  EXPECT_EQ(meter.find(disk).status, SideStatus::kNoNose);
  cv::Mat box(480, 640, CV_8UC1, 0.0);
  cv::rectangle(box, {200, 100}, {400, 400}, cv::Scalar(180), cv::FILLED);
  EXPECT_FALSE(meter.find(box).ok());
  // A nose-like wedge without lips below it.
  cv::Mat wedge(480, 640, CV_8UC1, 0.0);
  const std::vector<cv::Point> outline{{200, 50},  {330, 50},  {300, 150}, {420, 240},
                                       {320, 260}, {320, 450}, {200, 450}};
  cv::fillPoly(wedge, std::vector{outline}, cv::Scalar(180));
  EXPECT_EQ(meter.find(wedge).status, SideStatus::kNoLip);
}

TEST(SideProfile, CalibrationNeedsACompleteProfile) {
  SideProfileMeter meter;
  const std::vector<cv::Mat> blank{cv::Mat(480, 640, CV_8UC1, 0.0), cv::Mat(480, 640, CV_8UC1, 90.0)};
  EXPECT_THROW(calibrate_side(meter, blank), SideCalibrationError);
}

// The generated fixture: every frame measured, calibrated on the opening silence (the
// first 0.6 s are neutral), compared with the truth of the 3D shape (docs/method.md 5).
TEST(SideViewFixture, MeasureFollowsTheTruthOverTheClip) {
  const fs::path dir = test::kFixtureDir;
  const std::vector<double> truth = numeric_column(read_csv_table(dir / "side_view_truth.csv"), "protrusion_truth");
  cv::VideoCapture capture((dir / "side_view.avi").string());
  ASSERT_TRUE(capture.isOpened());
  std::vector<cv::Mat> frames;
  for (cv::Mat bgr, grey; capture.read(bgr);) {
    cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
    frames.push_back(grey.clone());
  }
  ASSERT_EQ(frames.size(), truth.size());
  ASSERT_EQ(truth.front(), 0.0);

  SideProfileMeter meter;  // the fixture faces right
  const auto neutral = std::span(frames).first(15);
  const SideReference reference = calibrate_side(meter, neutral);
  std::vector<double> measured;
  for (const cv::Mat& frame : frames) {
    const SideMeasure m = meter.measure(frame, reference);
    EXPECT_TRUE(m.ok()) << "frame " << measured.size();
    measured.push_back(m.protrusion);
  }
  const SeriesAgreement a = compare_series(truth, measured);
  std::printf(
      "[ figures  ] fixture, %d frames: scaled RMSE %.4f, Pearson r %.4f, MAE %.4f, max error %.4f, "
      "std ratio %.3f (truth range %.4f..%.4f)\n",
      a.pairs_used, a.rmse_scaled, a.pearson_r, a.mae, a.max_abs_error, a.std_ratio, *std::ranges::min_element(truth),
      *std::ranges::max_element(truth));
  EXPECT_EQ(a.pairs_used, static_cast<int>(truth.size()));
  EXPECT_GE(a.pearson_r, 0.95);
  EXPECT_LE(a.rmse_scaled, 0.1);  // docs/method.md 5 reference: 0.157-0.266 on real video
  EXPECT_NEAR(a.std_ratio, 1.0, 0.15);
}

}  // namespace
}  // namespace lipdrive
