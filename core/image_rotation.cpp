#include "core/image_rotation.hpp"

#include <opencv2/core.hpp>

namespace lipdrive {

std::optional<Rotation> rotation_from_degrees(int degrees) {
  switch (degrees) {
    case 0: return Rotation::k0;
    case 90: return Rotation::k90;
    case 180: return Rotation::k180;
    case 270: return Rotation::k270;
    default: return std::nullopt;
  }
}

void rotate_plane(const cv::Mat& in, cv::Mat& out, Rotation rotation) {
  if (in.empty()) {
    out.release();
    return;
  }
  switch (rotation) {
    case Rotation::k0: in.copyTo(out); return;
    case Rotation::k90: cv::rotate(in, out, cv::ROTATE_90_CLOCKWISE); return;
    case Rotation::k180: cv::rotate(in, out, cv::ROTATE_180); return;
    case Rotation::k270: cv::rotate(in, out, cv::ROTATE_90_COUNTERCLOCKWISE); return;
  }
}

}  // namespace lipdrive
