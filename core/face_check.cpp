#include "core/face_check.hpp"

#include "core/luma_sampling.hpp"

#include <Eigen/Core>

#include <cmath>

namespace lipdrive {
namespace {

using Vec2 = Eigen::Vector2d;
using Grid = std::array<float, FaceAppearance::kSamples>;

// The grid in face units (the distance between the eye centres), relative to the centroid of
// the eyes and nose (landmarks 27..47), which is steadier than any point: the upper face across
// from the outer right eye corner to the outer left one, down from the brows to the nose tip;
// the lower face across the mouth and a little beyond its corners, down from the nose tip to just
// below the lower lip (the chin, which the jaw moves most, left out).
struct GridBounds {
  double across_first, across_last, down_first, down_last;
};
constexpr GridBounds bounds(FaceRegion region) {
  return region == FaceRegion::kUpperFace ? GridBounds{-0.75, 0.75, -0.55, 0.5} : GridBounds{-0.55, 0.55, 0.45, 1.15};
}

enum class Sampled { kOutside, kFlat, kTextured };

/// Samples the grid of `region`. Mean-centred and normalised in place when it lies in the image
/// and has texture; `luma` is the mean it had.
Sampled sample_grid(const cv::Mat& gray, const Landmarks2D& p, FaceRegion region, Grid& grid, double& luma) {
  if (gray.empty() || gray.type() != CV_8UC1 || !p.allFinite()) return Sampled::kOutside;
  const GridBounds b = bounds(region);
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
  const double step_across = (b.across_last - b.across_first) / (FaceAppearance::kColumns - 1);
  const double step_down = (b.down_last - b.down_first) / (FaceAppearance::kRows - 1);
  const Vec2 tap_across = 0.25 * step_across * across, tap_down = 0.25 * step_down * down;
  double sum = 0;
  for (int r = 0; r < FaceAppearance::kRows; ++r)
    for (int c = 0; c < FaceAppearance::kColumns; ++c) {
      const Vec2 at = centre + (b.across_first + c * step_across) * across + (b.down_first + r * step_down) * down;
      float value = 0;
      for (const double sa : {-1.0, 1.0})
        for (const double sd : {-1.0, 1.0}) {
          const Vec2 tap = at + sa * tap_across + sd * tap_down;
          value += sample_luma(gray, tap.x(), tap.y());
        }
      if (std::isnan(value)) return Sampled::kOutside;
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
  if (norm < 1e-3 * FaceAppearance::kSamples) return Sampled::kFlat;  // a flat grey: nothing to correlate
  for (float& v : grid) v = static_cast<float>(v / norm);
  return Sampled::kTextured;
}

}  // namespace

bool FaceAppearance::capture(const cv::Mat& gray, const Landmarks2D& landmarks) {
  captured_ = sample_grid(gray, landmarks, region_, template_, luma_) == Sampled::kTextured;
  return captured_;
}

FaceAppearance::Match FaceAppearance::compare(const cv::Mat& gray, const Landmarks2D& landmarks) const {
  Match match;
  if (!captured_) return match;
  const Sampled sampled = sample_grid(gray, landmarks, region_, match.grid, match.luma);
  match.in_picture = sampled != Sampled::kOutside;
  match.textured = sampled == Sampled::kTextured;
  if (!match.textured) return match;
  match.similarity = 0;
  for (int i = 0; i < kSamples; ++i) match.similarity += static_cast<double>(template_[i]) * match.grid[i];
  return match;
}

void FaceAppearance::take(const Match& match) {
  captured_ = match.textured;
  if (!captured_) return;
  template_ = match.grid;
  luma_ = match.luma;
}

}  // namespace lipdrive
