#include "sim/steady_take.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>

namespace lipdrive {

SteadyTake steady_take(const cv::Mat& photo, const Landmarks2D& face, int frames, double interocular_px) {
  const Eigen::Vector2d low = face.rowwise().minCoeff(), high = face.rowwise().maxCoeff();
  const Eigen::Vector2d centre = 0.5 * (low + high);
  const double scale = interocular_px / interocular_distance(face);
  const cv::Size canvas(2 * static_cast<int>(1.5 * (high.x() - low.x()) * scale),
                        2 * static_cast<int>(1.5 * (high.y() - low.y()) * scale));
  // Periods in frames, prime to one another, so that no two movements keep in step.
  const auto wave = [](int f, double period) { return std::sin(2 * std::numbers::pi * f / period); };
  cv::RNG random(7);
  SteadyTake take;
  for (int f = 0; f < frames; ++f) {
    cv::Mat m =
        cv::getRotationMatrix2D(cv::Point2d(centre.x(), centre.y()), 3 * wave(f, 40), scale * (1 + 0.03 * wave(f, 53)));
    m.at<double>(0, 2) += canvas.width / 2.0 - centre.x() + 0.03 * canvas.width * wave(f, 31);
    m.at<double>(1, 2) += canvas.height / 2.0 - centre.y() + 0.03 * canvas.height * wave(f + 9, 37);
    cv::Mat frame, noise(canvas, CV_MAKETYPE(CV_32F, photo.channels()));
    cv::warpAffine(photo, frame, m, canvas, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    random.fill(noise, cv::RNG::NORMAL, 0, 2);
    frame.convertTo(frame, noise.type(), 1 + 0.1 * wave(f, 47));
    frame += noise;
    frame.convertTo(frame, photo.type());
    take.frames.push_back(frame);
    take.where.push_back(Eigen::Map<const Eigen::Matrix<double, 2, 3, Eigen::RowMajor>>(m.ptr<double>()));
  }
  return take;
}

}  // namespace lipdrive
