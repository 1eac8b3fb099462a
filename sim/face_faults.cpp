#include "sim/face_faults.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace lipdrive {

cv::Mat shifted_frame(const cv::Mat& gray, double dx, double dy, int fill) {
  const cv::Mat move = (cv::Mat_<double>(2, 3) << 1, 0, dx, 0, 1, dy);
  cv::Mat out;
  if (fill < 0)
    cv::warpAffine(gray, out, move, gray.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  else
    cv::warpAffine(gray, out, move, gray.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(fill));
  return out;
}

cv::Mat covered_frame(const cv::Mat& gray, double fraction, double luma, std::uint64_t seed) {
  cv::Mat out = gray.clone();
  const int rows = static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * gray.rows));
  if (rows == 0) return out;
  cv::Mat cover(rows, gray.cols, CV_8UC1);
  cv::RNG random(seed);
  random.fill(cover, cv::RNG::NORMAL, luma, 8);
  cv::GaussianBlur(cover, cover, cv::Size(0, 0), 3);
  cover.copyTo(out(cv::Rect(0, gray.rows - rows, gray.cols, rows)));
  return out;
}

cv::Mat held_before(const cv::Mat& image, const cv::Rect& area, const cv::Mat& thing) {
  cv::Mat out = image.clone();
  const cv::Rect covered = area & cv::Rect(0, 0, image.cols, image.rows);
  if (covered.empty()) return out;
  cv::Mat scaled;
  cv::resize(thing, scaled, area.size(), 0, 0, cv::INTER_LINEAR);
  scaled(cv::Rect(covered.tl() - area.tl(), covered.size())).copyTo(out(covered));
  return out;
}

cv::Rect before_the_mouth(const Landmarks2D& face) {
  const double margin = 0.3 * interocular_distance(face);
  const auto mouth = face.middleCols<20>(ibug::kMouthCornerRight);
  const Eigen::Vector2d low = mouth.rowwise().minCoeff().array() - margin,
                        high = mouth.rowwise().maxCoeff().array() + margin;
  return {cv::Point(low.x(), low.y()), cv::Point(high.x(), high.y())};
}

cv::Mat hand_of(const cv::Mat& image, const Landmarks2D& face) {
  const double iod = interocular_distance(face), brows = std::min(face(1, 19), face(1, 24));
  const cv::Rect forehead(cv::Point(face(0, 19), brows - 0.55 * iod), cv::Point(face(0, 24), brows - 0.15 * iod));
  return image(forehead & cv::Rect(0, 0, image.cols, image.rows)).clone();
}

}  // namespace lipdrive
