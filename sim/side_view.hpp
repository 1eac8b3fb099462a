// The side camera's view of the built-in head: its poses rendered in profile, with the
// ground truth of upper-lip protrusion taken from the 3D shape (docs/method.md 4, last
// bullet). The fixture clip follows a scripted trajectory of neutral, rounded and open
// visemes at several intensities.
#pragma once

#include "sim/mesh_renderer.hpp"
#include "sim/synthetic_head.hpp"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <vector>

namespace lipdrive {

struct SideViewOptions {
  cv::Size frame_size{640, 480};  // what a head-mounted camera delivers
  /// +90: the camera on the subject's right, the face looking towards image right;
  /// -90: the left profile, looking towards image left (mesh_renderer.hpp).
  float yaw_degrees = 90;
  float margin = 0.06f;  // fraction of the frame left free around every pose
};

/// Ground truth of one shape of the head: how far the upper-lip midpoint (landmark 51)
/// has moved out of the face since the neutral pose, over the neutral nose root–tip
/// distance (landmarks 27 and 30): (z51 - neutral z51) / |p27 - p30|. Positive = forward.
double upper_lip_protrusion(const SyntheticHead& head, const Eigen::Matrix3Xf& vertices);

/// One projection for every pose of `head` (their joint bounding box fitted into the
/// frame), so a clip of these poses shows a head that stays still while the jaw drops.
ImageProjection side_projection(const SyntheticHead& head, const SideViewOptions& options);

/// The shape `vertices` of the head rendered in profile (8-bit BGR, black background).
cv::Mat render_side_view(const SyntheticHead& head, const Eigen::Matrix3Xf& vertices, const cv::Size& frame_size,
                         const ImageProjection& projection);

/// A shape of one clip frame: a blend of two of the head's poses (indices into head.poses).
struct PoseBlend {
  int from = 0, to = 0;
  float weight = 0;  // 0 = `from`, 1 = `to`
};

/// The scripted side-view clip, one blend per frame at `fps`, a little over 8 s: silences,
/// rounded visemes (W, Ooh-Q, Oh, R, Ch-J-Sh), open and spread ones (BigAah, Aah, Eee),
/// lip press and tuck (B-M-P, F-V) at several intensities. Needs the Full161 pose set;
/// throws std::invalid_argument when a scripted pose is missing or fps is not positive.
std::vector<PoseBlend> side_view_trajectory(const SyntheticHead& head, double fps);

/// The vertices of a blend (linear between the two poses).
Eigen::Matrix3Xf blend_vertices(const SyntheticHead& head, const PoseBlend& blend);

}  // namespace lipdrive
