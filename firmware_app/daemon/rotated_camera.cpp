#include "firmware_app/daemon/rotated_camera.hpp"

#include <fmt/format.h>

namespace lipdrive {

RotatedCamera::RotatedCamera(std::unique_ptr<FrameSource> camera, Rotation rotation)
    : camera_(std::move(camera)), rotation_(rotation) {}

GrabStatus RotatedCamera::grab(Frame& frame, std::chrono::milliseconds timeout) {
  const GrabStatus status = camera_->grab(frame, timeout);
  if (status != GrabStatus::kFrame) return status;
  rotate_plane(frame.gray, gray_, rotation_);
  rotate_plane(frame.cr, cr_, rotation_);
  frame.gray = gray_;
  frame.cr = cr_;
  return status;
}

std::string RotatedCamera::describe() const {
  return fmt::format("{} (turned {}°)", camera_->describe(), static_cast<int>(rotation_));
}

std::unique_ptr<FrameSource> upright(std::unique_ptr<FrameSource> camera, Rotation rotation) {
  if (rotation == Rotation::k0) return camera;
  return std::make_unique<RotatedCamera>(std::move(camera), rotation);
}

}  // namespace lipdrive
