// Reading an 8-bit image plane between pixel centres, for measures that follow the landmarks at
// sub-pixel positions (lip contact, face appearance check).
#pragma once

#include <opencv2/core/mat.hpp>

#include <cmath>
#include <cstdint>
#include <limits>

namespace lipdrive {

/// Bilinear interpolation of the 8-bit luma image `gray` (CV_8UC1, any stride) at (x, y),
/// pixel centres on integers; NaN when the 2x2 neighbourhood is not inside the image.
inline float sample_luma(const cv::Mat& gray, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
  if (!(fx >= 0 && fy >= 0) || x0 + 1 >= gray.cols || y0 + 1 >= gray.rows)
    return std::numeric_limits<float>::quiet_NaN();
  const float ax = static_cast<float>(x - fx), ay = static_cast<float>(y - fy);
  const std::uint8_t* top = gray.ptr<std::uint8_t>(y0) + x0;
  const std::uint8_t* bottom = gray.ptr<std::uint8_t>(y0 + 1) + x0;
  const float upper = top[0] + ax * (static_cast<float>(top[1]) - top[0]);
  const float lower = bottom[0] + ax * (static_cast<float>(bottom[1]) - bottom[0]);
  return upper + ay * (lower - upper);
}

/// A plane sampled more coarsely than the luma (a camera's 4:2:0 or 4:2:2 chroma), read at luma
/// positions: the planes' pixel centres aligned, the scale taken once.
class SubsampledPlane {
 public:
  SubsampledPlane(const cv::Mat& plane, const cv::Mat& luma)
      : plane_(plane),
        sx_(static_cast<double>(plane.cols) / luma.cols),
        sy_(static_cast<double>(plane.rows) / luma.rows) {}
  /// sample_luma's bilinear value at luma pixel (x, y).
  float at(double x, double y) const { return sample_luma(plane_, (x + 0.5) * sx_ - 0.5, (y + 0.5) * sy_ - 0.5); }

 private:
  const cv::Mat& plane_;
  double sx_, sy_;
};

}  // namespace lipdrive
