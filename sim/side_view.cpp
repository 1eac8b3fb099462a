#include "sim/side_view.hpp"

#include "core/landmarks.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <stdexcept>
#include <string>
#include <string_view>

namespace lipdrive {
namespace {

// Keyframes of the script: a pose held at each time, smooth transitions in between
// (0.3–0.5 s, syllable rate). Rounded visemes push the lips forward by different amounts;
// the open, spread, pressed and tucked ones hardly move the upper lip's depth, so a
// measure that follows the jaw or the mouth width instead of protrusion shows up.
struct Keyframe {
  double time_s;
  std::string_view pose;
};
constexpr Keyframe kScript[] = {
    {0.0, "neutral"},     {0.6, "neutral"},   {1.0, "W_100"},     {1.4, "W_100"},     {1.8, "neutral"},
    {2.2, "BigAah_080"},  {2.6, "neutral"},   {3.0, "Ooh-Q_050"}, {3.4, "Oh_100"},    {3.8, "Aah_100"},
    {4.2, "Ooh-Q_100"},   {4.6, "Ooh-Q_100"}, {5.0, "Eee_100"},   {5.4, "R_070"},     {5.8, "B-M-P_100"},
    {6.2, "Ch-J-Sh_100"}, {6.6, "F-V_100"},   {7.0, "W_060"},     {7.4, "Ooh-Q_030"}, {7.8, "neutral"},
    {8.4, "neutral"},
};

double smoothstep(double t) { return t * t * (3 - 2 * t); }

int pose_index(const SyntheticHead& head, std::string_view name) {
  const auto it = std::ranges::find(head.poses, name, &HeadPose::name);
  if (it == head.poses.end())
    throw std::invalid_argument("side_view_trajectory: the head has no pose " + std::string(name));
  return static_cast<int>(it - head.poses.begin());
}

Eigen::Vector3f landmark(const SyntheticHead& head, const Eigen::Matrix3Xf& vertices, int index) {
  return vertices.col(head.landmark_vertex[static_cast<std::size_t>(index)]);
}

}  // namespace

double upper_lip_protrusion(const SyntheticHead& head, const Eigen::Matrix3Xf& vertices) {
  const Eigen::Matrix3Xf& neutral = head.poses.front().vertices;
  const double nose_length =
      (landmark(head, neutral, ibug::kNoseRoot) - landmark(head, neutral, ibug::kNoseTip)).norm();
  return (landmark(head, vertices, ibug::kOuterLipTop).z() - landmark(head, neutral, ibug::kOuterLipTop).z()) /
         nose_length;
}

ImageProjection side_projection(const SyntheticHead& head, const SideViewOptions& options) {
  if (head.poses.empty()) throw std::invalid_argument("side_projection: the head has no poses");
  // The view only turns about the vertical axis by a right angle, so the corners of the
  // poses' joint bounding box project onto exactly the extent of the poses themselves.
  Eigen::Vector3f lo = head.poses.front().vertices.rowwise().minCoeff();
  Eigen::Vector3f hi = head.poses.front().vertices.rowwise().maxCoeff();
  for (const HeadPose& pose : head.poses) {
    lo = lo.cwiseMin(pose.vertices.rowwise().minCoeff());
    hi = hi.cwiseMax(pose.vertices.rowwise().maxCoeff());
  }
  Eigen::Matrix3Xf corners(3, 8);
  for (int k = 0; k < 8; ++k) corners.col(k) << (k & 1 ? hi : lo).x(), (k & 2 ? hi : lo).y(), (k & 4 ? hi : lo).z();
  return fit_projection(corners, {options.yaw_degrees, options.frame_size, options.margin});
}

cv::Mat render_side_view(const SyntheticHead& head, const Eigen::Matrix3Xf& vertices, const cv::Size& frame_size,
                         const ImageProjection& projection) {
  return render_mesh(Mesh{vertices, head.triangles}, frame_size, projection);
}

std::vector<PoseBlend> side_view_trajectory(const SyntheticHead& head, double fps) {
  if (!(fps > 0)) throw std::invalid_argument("side_view_trajectory: the frame rate must be positive");
  int index[std::size(kScript)];
  for (std::size_t k = 0; k < std::size(kScript); ++k) index[k] = pose_index(head, kScript[k].pose);

  const double duration = std::end(kScript)[-1].time_s;
  const auto frames = static_cast<int>(std::floor(duration * fps)) + 1;
  std::vector<PoseBlend> blends;
  blends.reserve(static_cast<std::size_t>(frames));
  std::size_t k = 0;
  for (int f = 0; f < frames; ++f) {
    const double t = f / fps;
    while (k + 2 < std::size(kScript) && kScript[k + 1].time_s <= t) ++k;
    const double along = std::clamp((t - kScript[k].time_s) / (kScript[k + 1].time_s - kScript[k].time_s), 0.0, 1.0);
    blends.push_back({index[k], index[k + 1], static_cast<float>(smoothstep(along))});
  }
  return blends;
}

Eigen::Matrix3Xf blend_vertices(const SyntheticHead& head, const PoseBlend& blend) {
  const Eigen::Matrix3Xf& from = head.poses.at(static_cast<std::size_t>(blend.from)).vertices;
  const Eigen::Matrix3Xf& to = head.poses.at(static_cast<std::size_t>(blend.to)).vertices;
  return (1 - blend.weight) * from + blend.weight * to;
}

}  // namespace lipdrive
