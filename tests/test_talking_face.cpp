#include "build_paths.hpp"
#include "fixture_paths.hpp"
#include "sim/simulated_camera.hpp"
#include "sim/talking_face.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

// A hand-made frontal face in a 400x400 image: points on ellipses and lines where the
// iBUG 68 landmarks lie on a real face (in iBUG order: lower halves of the eyes and
// lips run back from the subject's left to right), with the inner lips slightly parted.
Landmarks2D synthetic_landmarks() {
  Landmarks2D p;
  const auto arc = [&](int first, int last, double cx, double cy, double rx, double ry, double from, double to) {
    for (int i = first; i <= last; ++i) {
      const double t = from + (to - from) * (i - first) / (last - first);
      p.col(i) << cx + rx * std::cos(t), cy + ry * std::sin(t);
    }
  };
  constexpr double pi = std::numbers::pi;
  arc(0, 16, 200, 180, 110, 140, pi, 0);                                // jaw: left ear, chin, right ear
  arc(17, 21, 150, 150, 40, 15, pi, 2 * pi);                            // right brow
  arc(22, 26, 250, 150, 40, 15, pi, 2 * pi);                            // left brow
  for (int i = 27; i <= 30; ++i) p.col(i) << 200, 170 + 15 * (i - 27);  // nose bridge
  arc(31, 35, 200, 210, 25, 8, 0.9 * pi, 0.1 * pi);                     // lower nose
  arc(36, 39, 150, 175, 22, 8, pi, 2 * pi);                             // right eye, upper lid
  arc(40, 41, 150, 175, 22, 8, pi / 3, 2 * pi / 3);                     // right eye, lower lid
  arc(42, 45, 250, 175, 22, 8, pi, 2 * pi);                             // left eye, upper lid
  arc(46, 47, 250, 175, 22, 8, pi / 3, 2 * pi / 3);                     // left eye, lower lid
  arc(48, 54, 200, 255, 45, 14, pi, 2 * pi);                            // outer lip, top
  arc(55, 59, 200, 255, 45, 16, pi / 6, 5 * pi / 6);                    // outer lip, bottom
  arc(60, 64, 200, 255, 34, 4, pi, 2 * pi);                             // inner lip, top
  arc(65, 67, 200, 255, 34, 4, pi / 4, 3 * pi / 4);                     // inner lip, bottom
  return p;
}

cv::Mat synthetic_portrait() {
  cv::Mat image(400, 400, CV_8UC3);
  cv::RNG rng(7);
  rng.fill(image, cv::RNG::UNIFORM, cv::Scalar::all(60), cv::Scalar::all(200));
  cv::GaussianBlur(image, image, {}, 2);
  return image;
}

double signed_area(const cv::Point2d& a, const cv::Point2d& b, const cv::Point2d& c) {
  return (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
}

double mean_luma_inside(const cv::Mat& bgr, const Landmarks2D& landmarks, int first, int last) {
  std::vector<cv::Point> ring;
  for (int i = first; i <= last; ++i) ring.emplace_back(cvRound(landmarks(0, i)), cvRound(landmarks(1, i)));
  cv::Mat mask(bgr.size(), CV_8UC1, cv::Scalar(0));
  cv::fillPoly(mask, std::vector{ring}, cv::Scalar(255));
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  return cv::mean(gray, mask)[0];
}

class TalkingFaceTest : public ::testing::Test {
 protected:
  TalkingFace face_{synthetic_portrait(), synthetic_landmarks()};
};

TEST_F(TalkingFaceTest, IsDeterministic) {
  const TalkingFace again(synthetic_portrait(), synthetic_landmarks());
  const MouthPose pose{0.7, 0.2, 0.1};
  const auto a = face_.frame(pose);
  const auto b = again.frame(pose);
  ASSERT_EQ(a.image.size(), cv::Size(640, 480));
  EXPECT_EQ(cv::norm(a.image, b.image, cv::NORM_INF), 0);
  EXPECT_EQ(a.landmarks, b.landmarks);
  EXPECT_EQ(scripted_trajectory(25).size(), scripted_trajectory(25).size());
}

TEST_F(TalkingFaceTest, TruthIsTheMouthRatiosOfTheMovedLandmarks) {
  for (const auto& pose : {MouthPose{}, MouthPose{1, 0, 0}, MouthPose{0.3, 1, 0}, MouthPose{0.1, 0, 1}}) {
    const auto frame = face_.frame(pose);
    const auto& p = frame.landmarks;
    const double d = ((p.col(39) + p.col(42)) / 2 - p.col(30)).norm();
    EXPECT_NEAR(frame.truth.width, (p.col(60) - p.col(64)).norm() / d, 1e-12);
    EXPECT_NEAR(frame.truth.height, (p.col(62) - p.col(66)).norm() / d, 1e-12);
  }
}

TEST_F(TalkingFaceTest, NeutralIsClosedAndPosesMoveTheMouthTheRightWay) {
  const auto neutral = face_.frame({});
  EXPECT_NEAR(neutral.truth.height, 0, 1e-12);
  const auto open = face_.frame({1, 0, 0});
  const auto spread = face_.frame({0, 1, 0});
  const auto round = face_.frame({0, 0, 1});
  EXPECT_GT(open.truth.height, 0.3);
  EXPECT_GT(spread.truth.width, neutral.truth.width * 1.1);
  EXPECT_LT(round.truth.width, neutral.truth.width * 0.85);
  EXPECT_GT(round.truth.height, 0);
  // The face above the mouth does not move: eyes and nose stay put.
  for (int i = 17; i <= 47; ++i) EXPECT_EQ(open.landmarks.col(i), neutral.landmarks.col(i)) << "landmark " << i;
}

TEST_F(TalkingFaceTest, OnlyTheLowerFaceChanges) {
  const auto neutral = face_.frame({});
  const auto open = face_.frame({1, 0.5, 0});
  // The eyes and everything above them are outside every moved triangle.
  const int eye_row = static_cast<int>(neutral.landmarks.row(1).segment(36, 12).maxCoeff());
  const cv::Rect upper(0, 0, 640, eye_row);
  EXPECT_EQ(cv::norm(neutral.image(upper), open.image(upper), cv::NORM_INF), 0);
  EXPECT_GT(cv::norm(neutral.image, open.image, cv::NORM_INF), 50);
}

TEST_F(TalkingFaceTest, TheOpenMouthIsADarkCavity) {
  const auto open = face_.frame({1, 0, 0});
  const double inside = mean_luma_inside(open.image, open.landmarks, 60, 67);
  const double lips = mean_luma_inside(open.image, open.landmarks, 48, 59);
  EXPECT_LT(inside, 50);
  EXPECT_GT(lips, inside + 30);
}

TEST_F(TalkingFaceTest, TheWarpNeverFoldsOverTheTrajectory) {
  const auto rest = face_.control_points(face_.neutral_landmarks());
  for (const auto& pose : scripted_trajectory(25)) {
    const auto moved = face_.control_points(face_.landmarks(pose));
    for (const auto& [a, b, c] : face_.triangles()) {
      const double before = signed_area(rest[a], rest[b], rest[c]);
      const double after = signed_area(moved[a], moved[b], moved[c]);
      EXPECT_GE(before * after, -1e-6) << "triangle " << a << " " << b << " " << c << " folds";
    }
  }
}

TEST(TalkingFaceTrajectory, HasClosedAndOpenPhasesWithinRange) {
  const auto poses = scripted_trajectory(30);
  EXPECT_GT(poses.size(), 30u * 5);
  int longest_silence = 0, silence = 0;
  double widest = 0, most_spread = 0, most_round = 0;
  for (const auto& pose : poses) {
    for (const double value : {pose.open, pose.spread, pose.round}) {
      EXPECT_GE(value, 0);
      EXPECT_LE(value, 1);
    }
    const bool closed = pose.open == 0 && pose.spread == 0 && pose.round == 0;
    silence = closed ? silence + 1 : 0;
    longest_silence = std::max(longest_silence, silence);
    widest = std::max(widest, pose.open);
    most_spread = std::max(most_spread, pose.spread);
    most_round = std::max(most_round, pose.round);
  }
  EXPECT_GE(longest_silence, 15);  // at least half a second of still, closed lips
  EXPECT_GT(widest, 0.9);
  EXPECT_GT(most_spread, 0.9);
  EXPECT_GT(most_round, 0.9);
}

TEST(TalkingFaceInput, RejectsAnEmptyPortraitOrDegenerateLandmarks) {
  EXPECT_THROW(TalkingFace(cv::Mat(), synthetic_landmarks()), std::invalid_argument);
  EXPECT_THROW(TalkingFace(synthetic_portrait(), Landmarks2D::Zero()), std::invalid_argument);
}

TEST(TalkingFaceFixture, VideoHasOneFramePerTruthRow) {
  const fs::path dir = test::kFixtureDir;
  LIPDRIVE_REQUIRE_BUILT(dir / "talking_face.avi");
  std::ifstream truth(dir / "talking_face_truth.csv");
  std::string line;
  ASSERT_TRUE(std::getline(truth, line));
  EXPECT_EQ(line, "frame,time_s,width_2d,height_2d");
  int rows = 0;
  while (std::getline(truth, line))
    if (!line.empty()) ++rows;

  SimulatedCamera camera({.input = dir / "talking_face.avi"});
  Frame frame;
  int frames = 0;
  GrabStatus status;
  while ((status = camera.grab(frame, std::chrono::milliseconds(1000))) == GrabStatus::kFrame) ++frames;
  EXPECT_EQ(status, GrabStatus::kEndOfStream);
  EXPECT_GT(rows, 100);
  EXPECT_EQ(frames, rows);
}

}  // namespace
}  // namespace lipdrive
