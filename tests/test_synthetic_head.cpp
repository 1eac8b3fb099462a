// The built-in head: anatomical sanity of its landmarks in every pose, the pose set,
// and what the renderer makes of it.
#include "core/landmarks.hpp"
#include "sim/mesh_renderer.hpp"
#include "sim/synthetic_head.hpp"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <set>
#include <string>

namespace lipdrive {
namespace {

// Generated once: every test reads the same head.
const SyntheticHead& head161() {
  static const SyntheticHead head = generate_synthetic_head(HeadPoseSet::Full161);
  return head;
}

const HeadPose& pose(const std::string& name) {
  const auto& poses = head161().poses;
  const auto it = std::find_if(poses.begin(), poses.end(), [&](const HeadPose& p) { return p.name == name; });
  if (it == poses.end()) throw std::out_of_range("no pose " + name);
  return *it;
}

Eigen::Vector3f landmark(const HeadPose& p, int index) { return p.vertices.col(head161().landmark_vertex[index]); }

float inner_height(const HeadPose& p) { return std::abs(landmark(p, 62).y() - landmark(p, 66).y()); }
float inner_width(const HeadPose& p) { return (landmark(p, 60) - landmark(p, 64)).norm(); }

float min_y(const HeadPose& p, int first, int last) {
  float y = landmark(p, first).y();
  for (int i = first; i <= last; ++i) y = std::min(y, landmark(p, i).y());
  return y;
}
float max_y(const HeadPose& p, int first, int last) {
  float y = landmark(p, first).y();
  for (int i = first; i <= last; ++i) y = std::max(y, landmark(p, i).y());
  return y;
}

TEST(SyntheticHead, PoseCountsAndNames) {
  const SyntheticHead small = generate_synthetic_head(HeadPoseSet::FullIntensity17);
  ASSERT_EQ(head161().poses.size(), 161u);
  ASSERT_EQ(small.poses.size(), 17u);
  EXPECT_EQ(head161().poses.front().name, "neutral");
  EXPECT_EQ(small.poses.front().name, "neutral");
  std::set<std::string> names;
  for (const auto& p : head161().poses) names.insert(p.name);
  EXPECT_EQ(names.size(), 161u);
  for (std::string_view viseme : kVisemeNames) {
    for (int percent = 10; percent <= 100; percent += 10) {
      const std::string name = std::string(viseme) + "_" + (percent < 100 ? "0" : "") + std::to_string(percent);
      EXPECT_TRUE(names.count(name)) << name;
    }
    EXPECT_TRUE(std::any_of(small.poses.begin(), small.poses.end(), [&](const HeadPose& p) {
      return p.name == std::string(viseme) + "_100";
    })) << viseme;
  }
  EXPECT_TRUE(names.count("BigAah_030"));
  EXPECT_TRUE(names.count("B-M-P_100"));
}

TEST(SyntheticHead, MeshIsConsistent) {
  const auto& h = head161();
  const auto n = h.poses.front().vertices.cols();
  EXPECT_GE(n, 2000);
  for (const auto& p : h.poses) ASSERT_EQ(p.vertices.cols(), n) << p.name;
  for (const Triangle& t : h.triangles) {
    for (auto v : t) ASSERT_LT(v, static_cast<std::uint32_t>(n));
    ASSERT_TRUE(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
  }
  const std::set<std::int32_t> distinct(h.landmark_vertex.begin(), h.landmark_vertex.end());
  EXPECT_EQ(distinct.size(), static_cast<std::size_t>(kNumLandmarks));
  for (auto v : h.landmark_vertex) {
    EXPECT_GE(v, 0);
    EXPECT_LT(v, n);
  }
}

TEST(SyntheticHead, IsDeterministic) {
  const SyntheticHead again = generate_synthetic_head(HeadPoseSet::Full161);
  ASSERT_EQ(again.poses.size(), head161().poses.size());
  for (std::size_t i = 0; i < again.poses.size(); ++i)
    EXPECT_TRUE(again.poses[i].vertices == head161().poses[i].vertices) << again.poses[i].name;
  EXPECT_EQ(again.triangles, head161().triangles);
  EXPECT_EQ(again.landmark_vertex, head161().landmark_vertex);
}

TEST(SyntheticHead, NeutralAnatomy) {
  const HeadPose& n = pose("neutral");
  EXPECT_GT(min_y(n, 17, 26), max_y(n, 36, 47)) << "brows above the eyes";
  EXPECT_GT(min_y(n, 36, 47), landmark(n, 30).y()) << "eyes above the nose tip";
  EXPECT_GT(landmark(n, 30).y(), max_y(n, 48, 67)) << "nose tip above the mouth";
  EXPECT_GT(min_y(n, 48, 67), landmark(n, 8).y()) << "mouth above the chin";
  // Subject's right is -x: the right eye's outer corner and mouth corner are on the left of the image.
  EXPECT_LT(landmark(n, 36).x(), landmark(n, 48).x());
  EXPECT_GT(landmark(n, 45).x(), landmark(n, 54).x());
  EXPECT_LT(landmark(n, 0).x(), 0);
  EXPECT_GT(landmark(n, 16).x(), 0);
  EXPECT_LT(landmark(n, 36).x(), landmark(n, 39).x());  // outer then inner corner
  EXPECT_LT(landmark(n, 42).x(), landmark(n, 45).x());
  // The nose sticks out: its tip is the front-most landmark.
  for (int i = 0; i < kNumLandmarks; ++i) {
    if (i == 30) continue;
    EXPECT_GT(landmark(n, 30).z(), landmark(n, i).z()) << i;
  }
  // Proportions within 10 % of the anthropometric means the head is built from.
  EXPECT_NEAR(landmark(n, 27).y() - landmark(n, 8).y(), 120, 12);   // n–gn
  EXPECT_NEAR(landmark(n, 45).x() - landmark(n, 36).x(), 90, 9);    // ex–ex
  EXPECT_NEAR(landmark(n, 42).x() - landmark(n, 39).x(), 32, 3.2);  // en–en
  EXPECT_NEAR((landmark(n, 54) - landmark(n, 48)).norm(), 50, 5);   // ch–ch
  EXPECT_NEAR(landmark(n, 27).y() - landmark(n, 33).y(), 53, 5.3);  // n–sn
  EXPECT_LT(inner_height(n), 1.0f) << "lips closed at rest";
}

TEST(SyntheticHead, InnerLipRingInsideOuterInEveryPose) {
  for (const auto& p : head161().poses) {
    SCOPED_TRACE(p.name);
    EXPECT_GT(landmark(p, 60).x(), landmark(p, 48).x());
    EXPECT_LT(landmark(p, 60).x(), landmark(p, 54).x());
    EXPECT_GT(landmark(p, 64).x(), landmark(p, 48).x());
    EXPECT_LT(landmark(p, 64).x(), landmark(p, 54).x());
    EXPECT_LT(landmark(p, 62).y(), landmark(p, 51).y());
    EXPECT_GT(landmark(p, 66).y(), landmark(p, 57).y());
    EXPECT_GE(landmark(p, 62).y(), landmark(p, 66).y() - 1e-3f) << "lips do not pass through each other";
  }
}

TEST(SyntheticHead, VisemeShapes) {
  const HeadPose& neutral = pose("neutral");
  EXPECT_LT(inner_height(pose("B-M-P_100")), 1.0f);
  const float widest = inner_height(pose("BigAah_100"));
  for (const auto& p : head161().poses) {
    if (p.name == "BigAah_100") continue;
    EXPECT_LT(inner_height(p), widest) << p.name;
  }
  EXPECT_GT(inner_height(pose("Aah_100")), inner_height(pose("Th_100")));
  for (const char* rounded : {"Ooh-Q_100", "W_100"}) {
    EXPECT_GE(landmark(pose(rounded), 51).z(), landmark(neutral, 51).z() + 2) << rounded;
    EXPECT_GE(landmark(pose(rounded), 57).z(), landmark(neutral, 57).z() + 2) << rounded;
    EXPECT_LT(inner_width(pose(rounded)), inner_width(neutral)) << rounded;
  }
  EXPECT_GT(inner_width(pose("Eee_100")), inner_width(neutral));
  EXPECT_GT(inner_width(pose("i_100")), inner_width(neutral));
  // F-V: the lower lip moves back (under the upper teeth) while the jaw barely opens.
  EXPECT_LT(landmark(pose("F-V_100"), 57).z(), landmark(neutral, 57).z() - 2);
}

TEST(SyntheticHead, IntensityIsMonotone) {
  const float rest = inner_height(pose("neutral"));
  const float half = inner_height(pose("BigAah_050"));
  const float full = inner_height(pose("BigAah_100"));
  EXPECT_GT(half, rest);
  EXPECT_LT(half, full);
  float previous = rest;
  for (int percent = 10; percent <= 100; percent += 10) {
    const std::string name = std::string("Aah_") + (percent < 100 ? "0" : "") + std::to_string(percent);
    EXPECT_GT(inner_height(pose(name)), previous) << name;
    previous = inner_height(pose(name));
  }
}

TEST(SyntheticHead, UpperFaceDoesNotMoveWithTheMouth) {
  const HeadPose& neutral = pose("neutral");
  for (const char* name : {"BigAah_100", "W_100", "Eee_100"})
    for (int i : {27, 36, 39, 42, 45, 19, 24})
      EXPECT_LT((landmark(pose(name), i) - landmark(neutral, i)).norm(), 0.05f) << name << " landmark " << i;
}

// ---------------------------------------------------------------------------------
// Rendering.

Mesh mesh_of(const HeadPose& p) { return Mesh{p.vertices, head161().triangles}; }

bool skin_coloured(const cv::Vec3b& bgr) { return bgr[2] > 90 && bgr[2] > bgr[0] + 20 && bgr[1] > bgr[0]; }

TEST(MeshRenderer, FrontalNeutralLooksLikeAFaceOnABackground) {
  const RenderView view{0, cv::Size(320, 320)};
  const cv::Mat image = render_mesh(mesh_of(pose("neutral")), view);
  ASSERT_EQ(image.type(), CV_8UC3);
  ASSERT_EQ(image.size(), view.size);
  int skin = 0, total = 0;
  for (int y = 110; y < 210; ++y)
    for (int x = 110; x < 210; ++x, ++total) skin += skin_coloured(image.at<cv::Vec3b>(y, x));
  EXPECT_GT(skin, total * 8 / 10);
  for (const cv::Point corner : {cv::Point(2, 2), cv::Point(317, 2), cv::Point(2, 317), cv::Point(317, 317)})
    EXPECT_FALSE(skin_coloured(image.at<cv::Vec3b>(corner))) << corner;
  // The subject's right eye (landmark 36, x < 0) lands on the image's left half.
  const ImageProjection projection = fit_projection(pose("neutral").vertices, view);
  EXPECT_LT(projection.project(landmark(pose("neutral"), 36)).x(), 160);
  EXPECT_GT(projection.project(landmark(pose("neutral"), 45)).x(), 160);
  EXPECT_LT(projection.project(landmark(pose("neutral"), 27)).y(),
            projection.project(landmark(pose("neutral"), 8)).y());
}

TEST(MeshRenderer, RightProfileShowsTheNoseOnTheRight) {
  const RenderView view{90, cv::Size(320, 320)};
  const ImageProjection projection = fit_projection(pose("neutral").vertices, view);
  const Eigen::Vector2f tip = projection.project(landmark(pose("neutral"), 30));
  const Eigen::Vector2f ear_side = projection.project(landmark(pose("neutral"), 0));
  EXPECT_GT(tip.x(), ear_side.x());
  const cv::Mat image = render_mesh(mesh_of(pose("neutral")), view);
  EXPECT_TRUE(skin_coloured(image.at<cv::Vec3b>(cv::Point(tip.x() - 3, tip.y()))));
  EXPECT_FALSE(skin_coloured(image.at<cv::Vec3b>(cv::Point(tip.x() + 6, tip.y()))));
}

/// Mean grey level in a box between the projections of landmarks 62 and 66.
double mouth_brightness(const HeadPose& p, const RenderView& view) {
  const ImageProjection projection = fit_projection(p.vertices, view);
  const cv::Mat image = render_mesh(mesh_of(p), view);
  const Eigen::Vector2f top = projection.project(landmark(p, 62)), bottom = projection.project(landmark(p, 66));
  const int half_width = 6;
  const cv::Rect box(static_cast<int>(top.x()) - half_width, static_cast<int>(top.y()) - 2, 2 * half_width + 1,
                     std::max(5, static_cast<int>(bottom.y() - top.y()) + 4));
  cv::Mat grey;
  cv::cvtColor(image(box), grey, cv::COLOR_BGR2GRAY);
  return cv::mean(grey)[0];
}

TEST(MeshRenderer, OpenMouthIsADarkCavity) {
  const RenderView view{0, cv::Size(400, 400)};
  const double closed = mouth_brightness(pose("neutral"), view);
  const double open = mouth_brightness(pose("BigAah_100"), view);
  RecordProperty("closed_mouth_grey", std::to_string(closed));
  RecordProperty("open_mouth_grey", std::to_string(open));
  EXPECT_LT(open, closed / 2);
  EXPECT_GT(closed, 60);
}

// A fit's affine camera (pixels, y down) back to the projection that renders the head where the
// camera saw it: a scaled rotation is recovered exactly; a camera with shear and unequal scales
// keeps a true rotation and lands its points within the shear's size.
TEST(MeshRenderer, CameraProjectionRendersWhereTheCameraProjects) {
  const Eigen::Matrix3d rotation =
      (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()) * Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitX()) *
       Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  Eigen::Matrix<double, 3, 4> camera = Eigen::Matrix<double, 3, 4>::Zero();
  camera.topLeftCorner<2, 3>() << 1.7 * rotation.row(0), -1.7 * rotation.row(1);
  camera.block<2, 1>(0, 3) << 180, 140;
  camera(2, 3) = 1;
  const ImageProjection p = camera_projection(camera);
  EXPECT_NEAR(p.scale, 1.7, 1e-5);
  EXPECT_TRUE(p.rotation.isApprox(rotation.cast<float>(), 1e-5f)) << p.rotation;
  const Eigen::Matrix3Xf points = mesh_of(pose("neutral")).vertices;
  double worst = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector2d seen = camera.topLeftCorner<2, 3>() * points.col(i).cast<double>() + camera.block<2, 1>(0, 3);
    worst = std::max(worst, (p.project(points.col(i)).cast<double>() - seen).norm());
  }
  EXPECT_LT(worst, 1e-3) << "px";

  camera(0, 1) += 0.05;  // shear
  camera.row(1) *= 1.1;  // and unequal scales
  camera(1, 3) = 140;
  const ImageProjection q = camera_projection(camera);
  EXPECT_TRUE((q.rotation * q.rotation.transpose()).isIdentity(1e-5f));
  EXPECT_NEAR(q.rotation.determinant(), 1, 1e-5);
  EXPECT_GT(q.scale, 1.7);
  EXPECT_LT(q.scale, 1.7 * 1.1);
}

}  // namespace
}  // namespace lipdrive
