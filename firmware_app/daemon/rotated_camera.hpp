// A camera whose frames are turned upright ([camera] rotation): wraps the camera's FrameSource
// and hands out its frames turned by a quarter turn, half turn or three quarters, clockwise.
//
// Thread model: that of the FrameSource it wraps (one owner thread calls grab()).
#pragma once

#include "core/image_rotation.hpp"
#include "drivers/frame_source.hpp"

#include <memory>

namespace lipdrive {

class RotatedCamera : public FrameSource {
 public:
  RotatedCamera(std::unique_ptr<FrameSource> camera, Rotation rotation);

  /// The camera's frame, its planes turned into buffers of this object's (valid until the next
  /// grab(), as any frame); after the first frame of a size, allocates nothing.
  GrabStatus grab(Frame& frame, std::chrono::milliseconds timeout) override;
  double frame_rate() const override { return camera_->frame_rate(); }
  std::string describe() const override;

 private:
  std::unique_ptr<FrameSource> camera_;
  Rotation rotation_;
  cv::Mat gray_, cr_;  // the turned planes
};

/// `camera` itself for Rotation::k0, else a RotatedCamera around it.
std::unique_ptr<FrameSource> upright(std::unique_ptr<FrameSource> camera, Rotation rotation);

}  // namespace lipdrive
