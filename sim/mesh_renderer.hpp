// A small software rasteriser for model meshes: orthographic view, z-buffer,
// Gouraud-interpolated Lambert shading. Used to look at models and to make
// synthetic camera frames.
#pragma once

#include "core/morphable_model.hpp"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

namespace lipdrive {

struct RenderView {
  /// Rotation of the head about the vertical axis, in degrees. 0 = frontal; +90 = the
  /// subject's right profile (the camera on the subject's right, face pointing to
  /// image right); -90 = the left profile.
  float yaw_degrees = 0;
  cv::Size size{640, 640};
  float margin = 0.06f;  // fraction of the image side left free around the mesh
};

/// Model space -> image pixels (x right, y down), plus the depth used by the z-buffer.
struct ImageProjection {
  Eigen::Matrix3f rotation;  // the view rotation (yaw)
  float scale = 1;           // pixels per millimetre
  Eigen::Vector2f offset;    // pixel position of the model-space origin after rotation

  Eigen::Vector2f project(const Eigen::Vector3f& vertex) const;
  float depth(const Eigen::Vector3f& vertex) const;  // larger = nearer the camera
};

/// The projection that fits `vertices` (seen from view.yaw_degrees) centred into
/// the image with view.margin left free on the tighter side.
ImageProjection fit_projection(const Eigen::Matrix3Xf& vertices, const RenderView& view);

/// The scaled orthographic projection nearest an affine camera that maps model space to image
/// pixels (image = camera * [X; 1], y down, as a fit's FitOutput::camera): its rotation from the
/// SVD of the camera's 2x3 part (the nearest orthonormal rows, Hartley & Zisserman 2004, 6.3.4),
/// its scale the mean of the two singular values. A fitted head then renders where it was seen.
ImageProjection camera_projection(const Eigen::Matrix<double, 3, 4>& camera);

/// Renders with fit_projection(mesh.vertices, view). 8-bit BGR.
cv::Mat render_mesh(const Mesh& mesh, const RenderView& view);

/// Renders with a given projection (e.g. one fitted to another pose, so that several
/// poses share a frame). Front faces are skin shaded by a light from the camera's
/// upper left; back faces (the inside of the head, seen through the open mouth) are
/// drawn dark; the background is black.
cv::Mat render_mesh(const Mesh& mesh, const cv::Size& size, const ImageProjection& projection);

}  // namespace lipdrive
