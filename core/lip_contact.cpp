#include "core/lip_contact.hpp"

#include "core/luma_sampling.hpp"
#include "core/statistics.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>

namespace lipdrive {
namespace {

using Vec2 = Eigen::Vector2d;

// The outer and inner lip contours as polylines from corner to corner (iBUG order).
constexpr std::array<int, 7> kOuterUpper{48, 49, 50, 51, 52, 53, 54};
constexpr std::array<int, 7> kOuterLower{48, 59, 58, 57, 56, 55, 54};
constexpr std::array<int, 5> kInnerUpper{60, 61, 62, 63, 64};
constexpr std::array<int, 5> kInnerLower{60, 67, 66, 65, 64};

/// The face's own axes, from the eye line: `across` points from the right eye to the left,
/// `down` is perpendicular to it, towards the chin.
struct FaceAxes {
  Vec2 across, down;
};

FaceAxes face_axes(const Landmarks2D& p) {
  const Vec2 across = (p.col(ibug::kLeftEyeOuter) - p.col(ibug::kRightEyeOuter)).normalized();
  return {across, Vec2(-across.y(), across.x())};
}

/// Where a contour crosses the line through `base` along `down`: its `down` coordinate
/// relative to `base`, interpolated between the two contour points either side of it
/// (clamped to the contour's ends).
template <std::size_t N>
double contour_depth(const Landmarks2D& p, const std::array<int, N>& contour, const FaceAxes& axes, const Vec2& base) {
  double previous_lateral = (p.col(contour[0]) - base).dot(axes.across);
  double previous_depth = (p.col(contour[0]) - base).dot(axes.down);
  if (previous_lateral >= 0) return previous_depth;
  for (std::size_t i = 1; i < N; ++i) {
    const double lateral = (p.col(contour[i]) - base).dot(axes.across);
    const double depth = (p.col(contour[i]) - base).dot(axes.down);
    if (lateral >= 0) {
      const double t = lateral > previous_lateral ? -previous_lateral / (lateral - previous_lateral) : 0.0;
      return previous_depth + t * (depth - previous_depth);
    }
    previous_lateral = lateral;
    previous_depth = depth;
  }
  return previous_depth;
}

/// One vertical profile: the samples, and where the lip contours cross it (sample indices,
/// fractional).
struct Profile {
  std::array<float, LipContactSettings::kSamples> luma{};
  std::array<float, LipContactSettings::kSamples> red{};  // Cr - 128; 0 without colour
  double outer_top = 0, inner_top = 0, inner_bottom = 0, outer_bottom = 0;
  double px_per_sample = 0;
};

/// Taps across each profile sample, spread over the profile's share of the mouth width: their
/// mean sees the same structures (teeth, the line between the lips) at any resolution and
/// smooths the lips' own fine texture (creases, gloss) that a high-resolution image shows.
constexpr int kTaps = 4;

/// `cr`: the Cr plane, or null (no colour: `red` stays 0).
bool read_profile(const cv::Mat& gray, const SubsampledPlane* cr, const Landmarks2D& p, const FaceAxes& axes,
                  const Vec2& base, double reach, double width, Profile& out) {
  const double outer_top = contour_depth(p, kOuterUpper, axes, base);
  const double outer_bottom = contour_depth(p, kOuterLower, axes, base);
  const double inner_top = contour_depth(p, kInnerUpper, axes, base);
  const double inner_bottom = contour_depth(p, kInnerLower, axes, base);
  const double first = outer_top - reach, last = outer_bottom + reach;
  if (!(last > first)) return false;
  constexpr int n = LipContactSettings::kSamples;
  const double step = (last - first) / (n - 1);
  for (int i = 0; i < n; ++i) {
    const Vec2 at = base + (first + i * step) * axes.down;
    float sum = 0, red = 0;
    for (int k = 0; k < kTaps; ++k) {
      const Vec2 tap = at + ((k + 0.5) / kTaps - 0.5) * width * axes.across;
      sum += sample_luma(gray, tap.x(), tap.y());
      if (cr != nullptr) red += cr->at(tap.x(), tap.y()) - 128.0f;
    }
    out.luma[i] = sum / kTaps;
    out.red[i] = red / kTaps;
    if (std::isnan(out.luma[i]) || std::isnan(out.red[i])) return false;
  }
  const auto index = [&](double depth) { return (depth - first) / step; };
  out.outer_top = index(outer_top);
  out.inner_top = index(std::max(inner_top, outer_top));
  out.inner_bottom = index(std::min(std::max(inner_bottom, inner_top), outer_bottom));
  out.outer_bottom = index(outer_bottom);
  out.px_per_sample = step;
  return true;
}

/// The samples where the lips meet or part: between the inner lip contours, widened by
/// `margin` (the landmarks' own error), within the outer contours.
struct Region {
  int first = 0, last = -1;
};

Region inner_region(const Profile& profile, double margin_samples) {
  return {static_cast<int>(std::ceil(std::max(profile.outer_top, profile.inner_top - margin_samples))),
          static_cast<int>(std::floor(std::min(profile.outer_bottom, profile.inner_bottom + margin_samples)))};
}

/// How far the region falls short of the lips, integrated along the profile: the sum of
/// (1 - value / lip value) over its samples below the lips', in pixels. With the luma that is
/// the darkness: blur spreads the line between sealed lips but keeps its integral, and a cavity
/// adds its contrast times its height, with no threshold on how dark it must be. With Cr - 128
/// it is the pallor: teeth and the mouth's inside are less red than the lips.
double deficit_px(const Profile& profile, const std::array<float, LipContactSettings::kSamples>& values,
                  const Region& region, double lip_value) {
  double sum = 0;
  for (int i = region.first; i <= region.last; ++i) sum += std::max(0.0, 1.0 - values[i] / lip_value);
  return sum * profile.px_per_sample;
}

/// How far the region's luma departs from a single valley, over the lips' luma: its total
/// variation less the way down to its darkest sample and up again. 0 for the line between
/// sealed lips; about twice the teeth's contrast for lip, teeth, cavity, teeth, lip.
double excess_variation(const Profile& profile, const Region& region, double lip_luma) {
  if (region.last <= region.first) return 0;
  const float* v = profile.luma.data();
  float lowest = v[region.first];
  double variation = 0;
  for (int i = region.first + 1; i <= region.last; ++i) {
    lowest = std::min(lowest, v[i]);
    variation += std::abs(v[i] - v[i - 1]);
  }
  const double valley = (v[region.first] - lowest) + (v[region.last] - lowest);
  return std::max(0.0, variation - valley) / lip_luma;
}

}  // namespace

LipGap measure_lip_gap(const cv::Mat& gray, const cv::Mat& cr, const Landmarks2D& p, const LipContactSettings& s) {
  LipGap result;
  if (gray.empty() || gray.type() != CV_8UC1 || !p.allFinite()) return result;
  const bool chroma = !cr.empty() && cr.type() == CV_8UC1 && cr.cols <= gray.cols && cr.rows <= gray.rows;
  const SubsampledPlane cr_plane(cr, gray);
  const double d = (0.5 * (p.col(ibug::kRightEyeInner) + p.col(ibug::kLeftEyeInner)) - p.col(ibug::kNoseTip)).norm();
  if (!(d > 1)) return result;
  const FaceAxes axes = face_axes(p);
  const double reach = s.extend * d;

  constexpr int kColumns = LipContactSettings::kColumns, n = LipContactSettings::kSamples;
  std::array<Profile, kColumns> profiles;
  std::array<double, kColumns * n> band{}, band_red{};  // lip band samples of every profile, for their medians
  int band_count = 0;
  const Vec2 right = p.col(ibug::kInnerCornerRight), left = p.col(ibug::kInnerCornerLeft);
  const double column_width = s.column_span * (left - right).norm() / kColumns;
  for (int c = 0; c < kColumns; ++c) {
    const double t = 0.5 + s.column_span * (static_cast<double>(c) / (kColumns - 1) - 0.5);
    Profile& profile = profiles[c];
    if (!read_profile(gray, chroma ? &cr_plane : nullptr, p, axes, right + t * (left - right), reach, column_width,
                      profile))
      return result;
    // The lip bands: from each outer contour to the inner contour on its side.
    for (int i = 0; i < n; ++i) {
      const bool upper = i >= profile.outer_top && i <= profile.inner_top;
      const bool lower = i >= profile.inner_bottom && i <= profile.outer_bottom;
      if (upper || lower) {
        band_red[band_count] = profile.red[i];
        band[band_count++] = profile.luma[i];
      }
    }
  }
  if (band_count < kColumns * 2) return result;
  result.lip_luma = median(std::span(band).first(static_cast<std::size_t>(band_count)));
  if (result.lip_luma < 8) return result;  // a black frame: nothing to compare against
  result.lip_red = median(std::span(band_red).first(static_cast<std::size_t>(band_count)));
  result.colour = chroma && result.lip_red >= s.min_lip_red;

  std::array<double, kColumns> darkness{}, textures{}, pallor{};
  for (int c = 0; c < kColumns; ++c) {
    const Profile& profile = profiles[c];
    const Region region = inner_region(profile, s.margin * d / profile.px_per_sample);
    if (region.last < region.first) return result;
    darkness[c] = std::max(0.0, deficit_px(profile, profile.luma, region, result.lip_luma) / d - s.line_darkness);
    textures[c] = excess_variation(profile, region, result.lip_luma);
    if (result.colour)
      pallor[c] = std::max(0.0, deficit_px(profile, profile.red, region, result.lip_red) - s.line_pallor_px) / d;
  }
  // Medians over the profiles: one profile on a lip crease or a stray highlight does not decide.
  result.darkness = median(darkness);
  result.texture = median(textures);
  result.pallor = median(pallor);
  result.valid = true;
  return result;
}

double seal_probability(const LipGap& gap, double landmark_height, const LipContactSettings& s) {
  if (!gap.valid) return 0;
  // With colour the pallor tells teeth and the mouth's inside from the lips; without it the
  // luma's texture stands in for it.
  const double apart = gap.colour ? gap.pallor / s.open_pallor : gap.texture / s.open_texture;
  const double evidence = std::max(gap.darkness / s.open_darkness, apart);
  const double pixels = 1.0 / (1.0 + std::exp((evidence - 1) / s.seal_softness));
  const double plausible = 1.0 / (1.0 + std::exp((landmark_height - s.max_sealed_height) / s.height_softness));
  return pixels * plausible;
}

double fused_opening(double landmark_height, double seal) { return (1 - seal) * landmark_height; }

}  // namespace lipdrive
