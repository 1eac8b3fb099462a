#include "core/face_check.hpp"

#include "core/luma_sampling.hpp"

#include <Eigen/Core>

#include <cmath>

namespace lipdrive {
namespace {

using Vec2 = Eigen::Vector2d;
using Grid = std::array<float, FaceAppearance::kSamples>;

// The grid in face units (the distance between the eye centres): across from the outer
// right eye corner to the outer left one, down from the brows to the nose tip, relative to
// the centroid of the eyes and nose (landmarks 27..47), which is steadier than any point.
constexpr double kAcrossFirst = -0.75, kAcrossLast = 0.75;
constexpr double kDownFirst = -0.55, kDownLast = 0.5;

/// Samples the grid; false when it leaves the image. Mean-centred and normalised in place,
/// false too when it has no texture at all; `luma` is the mean it had.
bool sample_grid(const cv::Mat& gray, const Landmarks2D& p, Grid& grid, double& luma) {
  if (gray.empty() || gray.type() != CV_8UC1 || !p.allFinite()) return false;
  Vec2 centre = Vec2::Zero();
  for (int i = ibug::kNoseRoot; i <= ibug::kLeftEyeOuter; ++i) centre += p.col(i);
  centre /= ibug::kLeftEyeOuter - ibug::kNoseRoot + 1;
  Vec2 right_eye = Vec2::Zero(), left_eye = Vec2::Zero();
  for (int i = 0; i < 6; ++i) {
    right_eye += p.col(ibug::kRightEyeOuter + i) / 6;
    left_eye += p.col(ibug::kLeftEyeInner + i) / 6;
  }
  const Vec2 across = left_eye - right_eye;  // one face unit long
  const Vec2 down(-across.y(), across.x());
  const double step_across = (kAcrossLast - kAcrossFirst) / (FaceAppearance::kColumns - 1);
  const double step_down = (kDownLast - kDownFirst) / (FaceAppearance::kRows - 1);
  const Vec2 tap_across = 0.25 * step_across * across, tap_down = 0.25 * step_down * down;
  double sum = 0;
  for (int r = 0; r < FaceAppearance::kRows; ++r)
    for (int c = 0; c < FaceAppearance::kColumns; ++c) {
      const Vec2 at = centre + (kAcrossFirst + c * step_across) * across + (kDownFirst + r * step_down) * down;
      float value = 0;
      for (const double sa : {-1.0, 1.0})
        for (const double sd : {-1.0, 1.0}) {
          const Vec2 tap = at + sa * tap_across + sd * tap_down;
          value += sample_luma(gray, tap.x(), tap.y());
        }
      if (std::isnan(value)) return false;
      grid[r * FaceAppearance::kColumns + c] = value;
      sum += value;
    }
  luma = sum / FaceAppearance::kSamples / 4;  // four taps per sample
  const float mean = static_cast<float>(sum / FaceAppearance::kSamples);
  double norm = 0;
  for (float& v : grid) {
    v -= mean;
    norm += static_cast<double>(v) * v;
  }
  norm = std::sqrt(norm);
  if (norm < 1e-3 * FaceAppearance::kSamples) return false;  // a flat grey: nothing to correlate
  for (float& v : grid) v = static_cast<float>(v / norm);
  return true;
}

}  // namespace

bool FaceAppearance::capture(const cv::Mat& gray, const Landmarks2D& landmarks) {
  captured_ = sample_grid(gray, landmarks, template_, luma_);
  return captured_;
}

FaceAppearance::Match FaceAppearance::compare(const cv::Mat& gray, const Landmarks2D& landmarks) const {
  Match match;
  Grid grid;
  if (!captured_ || !sample_grid(gray, landmarks, grid, match.luma)) return match;
  match.similarity = 0;
  for (int i = 0; i < kSamples; ++i) match.similarity += static_cast<double>(template_[i]) * grid[i];
  return match;
}

}  // namespace lipdrive
