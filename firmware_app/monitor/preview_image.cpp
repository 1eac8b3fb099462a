#include "firmware_app/monitor/preview_image.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <vector>

namespace lipdrive {
namespace {

constexpr int kShift = 4;  // sub-pixel bits of the drawing coordinates
const cv::Scalar kBoxColour(0, 220, 255), kLipColour(255, 0, 255), kLandmarkColour(0, 230, 0), kNoFaceColour(0, 0, 255);

/// Frame pixels to fixed-point canvas pixels.
cv::Point to_canvas(double x, double y, int decimation) {
  const double scale = (1 << kShift) / static_cast<double>(decimation);
  return {static_cast<int>(std::lround(x * scale)), static_cast<int>(std::lround(y * scale))};
}

cv::Point to_canvas(const cv::Point2f& point, int decimation) { return to_canvas(point.x, point.y, decimation); }

void dot(cv::Mat& canvas, const cv::Point2f& point, int decimation, const cv::Scalar& colour) {
  cv::circle(canvas, to_canvas(point, decimation), 3 << kShift, colour, cv::FILLED, cv::LINE_AA, kShift);
}

void warn(cv::Mat& canvas, const char* text, int line) {
  cv::putText(canvas, text, {8, 24 * line}, cv::FONT_HERSHEY_SIMPLEX, 0.7, kNoFaceColour, 2, cv::LINE_AA);
}

/// The closed contour through landmarks first..last of `points`; none when one is unmapped.
void draw_contour(cv::Mat& canvas, const Landmarks2D& points, int first, int last, int decimation) {
  std::vector<cv::Point> contour;
  for (int i = first; i <= last; ++i) {
    if (!std::isfinite(points(0, i)) || !std::isfinite(points(1, i))) return;
    contour.push_back(to_canvas(points(0, i), points(1, i), decimation));
  }
  cv::polylines(canvas, contour, true, kLipColour, 1, cv::LINE_AA, kShift);
}

}  // namespace

std::string preview_jpeg(const PreviewFrame& frame, cv::Mat& canvas, JpegEncoder& encoder) {
  cv::cvtColor(frame.image, canvas, cv::COLOR_GRAY2BGR);
  const int k = frame.decimation;
  if (frame.tracked) {
    const Eigen::Vector2d low = frame.landmarks.rowwise().minCoeff(), high = frame.landmarks.rowwise().maxCoeff();
    // Two pixels wide: a one-pixel anti-aliased line between two pixel rows is two half-tone rows,
    // faint once the page scales the JPEG (the browser test counted 2151 and then 588 yellow
    // pixels of a one-pixel box in two screenshots a moment apart).
    cv::rectangle(canvas, to_canvas(low.x(), low.y(), k), to_canvas(high.x(), high.y(), k), kBoxColour, 2, cv::LINE_AA,
                  kShift);
    draw_contour(canvas, frame.fitted, ibug::kMouthCornerRight, ibug::kInnerCornerRight - 1, k);  // outer lips 48-59
    draw_contour(canvas, frame.fitted, ibug::kInnerCornerRight, kNumLandmarks - 1, k);            // inner lips 60-67
    for (int i = 0; i < kNumLandmarks; ++i)
      cv::circle(canvas, to_canvas(frame.landmarks(0, i), frame.landmarks(1, i), k), 2 << kShift, kLandmarkColour,
                 cv::FILLED, cv::LINE_AA, kShift);
  } else {
    warn(canvas, "no face", 1);
  }
  return encoder.encode(canvas);
}

std::string side_preview_jpeg(const PreviewFrame& frame, cv::Mat& canvas, JpegEncoder& encoder) {
  cv::cvtColor(frame.side_image, canvas, cv::COLOR_GRAY2BGR);
  const int k = frame.side_decimation;
  const SideProfile& p = frame.side_profile;
  // The points are set as far as the search got (core/side_profile.hpp): the tip from kNoNose
  // on, the root from kNoLip on, the rest with kOk and kNotTheFace.
  if (p.status == SideStatus::kNoNose) dot(canvas, p.nose_tip, k, kBoxColour);
  if (p.status == SideStatus::kNoLip || p.status == SideStatus::kNotTheFace || p.ok()) {
    cv::line(canvas, to_canvas(p.nose_root, k), to_canvas(p.nose_tip, k), kBoxColour, 1, cv::LINE_AA, kShift);
    dot(canvas, p.nose_root, k, kBoxColour);
    dot(canvas, p.nose_tip, k, kBoxColour);
  }
  if (p.ok()) {
    dot(canvas, p.subnasale, k, kLandmarkColour);
    cv::line(canvas, to_canvas(p.nose_tip.x, p.upper_lip.y, k), to_canvas(p.upper_lip, k), kLipColour, 1, cv::LINE_AA,
             kShift);
    dot(canvas, p.upper_lip, k, kLipColour);
  }
  int line = 1;
  if (!frame.side_connected) warn(canvas, "side camera lost", line++);
  switch (p.status) {
    case SideStatus::kOk: break;
    case SideStatus::kEmptyCrop:
    case SideStatus::kNoSilhouette: warn(canvas, "no profile", line); break;
    case SideStatus::kNoNose: warn(canvas, "no nose", line); break;
    case SideStatus::kNoLip: warn(canvas, "no upper lip", line); break;
    case SideStatus::kNotTheFace: warn(canvas, "not the calibrated profile", line); break;
  }
  return encoder.encode(canvas);
}

}  // namespace lipdrive
