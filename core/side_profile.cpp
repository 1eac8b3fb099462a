#include "core/side_profile.hpp"

#include "core/statistics.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

namespace lipdrive {
namespace {

constexpr float kNone = std::numeric_limits<float>::quiet_NaN();

/// Otsu's threshold of a grey crop and the means of its two classes (Otsu, "A Threshold
/// Selection Method from Gray-Level Histograms", IEEE SMC 1979): the level that maximises
/// the between-class variance. Pixels <= threshold are one class, the rest the other.
struct OtsuSplit {
  int threshold = 0;
  double dark_mean = 0, bright_mean = 0;  // equal when the crop has one grey level
};

OtsuSplit otsu_split(const cv::Mat& crop) {
  std::array<double, 256> histogram{};
  for (int y = 0; y < crop.rows; ++y) {
    const auto* row = crop.ptr<std::uint8_t>(y);
    for (int x = 0; x < crop.cols; ++x) ++histogram[row[x]];
  }
  double total = 0, sum = 0;
  for (int level = 0; level < 256; ++level) total += histogram[level], sum += level * histogram[level];

  OtsuSplit best{0, sum / total, sum / total};
  double best_variance = -1, dark_count = 0, dark_sum = 0;
  for (int level = 0; level < 255; ++level) {
    dark_count += histogram[level];
    dark_sum += level * histogram[level];
    const double bright_count = total - dark_count;
    if (dark_count == 0) continue;
    if (bright_count == 0) break;
    const double dark_mean = dark_sum / dark_count, bright_mean = (sum - dark_sum) / bright_count;
    const double variance = dark_count * bright_count * (bright_mean - dark_mean) * (bright_mean - dark_mean);
    if (variance > best_variance) best_variance = variance, best = {level, dark_mean, bright_mean};
  }
  return best;
}

/// Column of the crop `k` pixels behind its front edge (the edge the face looks towards).
int column_from_front(const cv::Mat& crop, ProfileFacing facing, int k) {
  return facing == ProfileFacing::kRight ? crop.cols - 1 - k : k;
}

/// Whether the face is the bright class: the face looks into the background, so the crop's
/// front column is background, and its mean grey says on which side of Otsu's level that is.
bool face_is_bright(const cv::Mat& crop, ProfileFacing facing, const OtsuSplit& split) {
  const int x = column_from_front(crop, facing, 0);
  double sum = 0;
  for (int y = 0; y < crop.rows; ++y) sum += crop.ptr<std::uint8_t>(y)[x];
  return sum / crop.rows <= split.threshold;
}

/// The grey level that separates face from background: Otsu's level moved by `bias` of the
/// way towards the background class's mean (SideProfileSettings::background_bias), as the
/// last level still taken for background.
int face_threshold(const OtsuSplit& split, bool bright, double bias) {
  const double background = bright ? split.dark_mean : split.bright_mean;
  const double level = split.threshold + 0.5 + bias * (background - split.threshold - 0.5);
  return static_cast<int>(std::floor(level));
}

/// The outline of the silhouette: per row, the foremost face pixel that starts a run of
/// `min_run` face pixels, as a position along the facing direction (0 = the crop's back
/// edge). The edge is placed between that pixel and the background pixel in front of it
/// where the grey level crosses the threshold (linear interpolation), which recovers the
/// sub-pixel edge a camera's blur leaves. Rows without a face get NaN.
void scan_front_profile(const cv::Mat& crop, ProfileFacing facing, int threshold, bool bright, int min_run,
                        std::span<float> front) {
  const double level = threshold + 0.5;  // the decision boundary between two grey levels
  const auto is_face = [&](std::uint8_t v) { return bright ? v > threshold : v <= threshold; };
  for (int y = 0; y < crop.rows; ++y) {
    const auto* row = crop.ptr<std::uint8_t>(y);
    front[y] = kNone;
    int run = 0;
    for (int k = 0; k < crop.cols; ++k) {
      run = is_face(row[column_from_front(crop, facing, k)]) ? run + 1 : 0;
      if (run < min_run) continue;
      const int first = k - run + 1;
      double fraction = 0;  // of a pixel in front of `first`
      if (first > 0) {
        const double face = row[column_from_front(crop, facing, first)];
        const double background = row[column_from_front(crop, facing, first - 1)];
        fraction = (face - level) / (face - background);
      }
      front[y] = static_cast<float>(crop.cols - 1 - first + fraction);
      break;
    }
  }
}

/// The nose tip: the foremost outline point within the band of the silhouette's rows
/// where the nose is (settings), above the lips and the chin. -1 when the band is empty.
int find_nose_tip(std::span<const float> front, double band_top, double band_bottom) {
  const auto valid = [&](int r) { return !std::isnan(front[r]); };
  int first = 0, last = static_cast<int>(front.size()) - 1;
  while (first <= last && !valid(first)) ++first;
  while (last >= first && !valid(last)) --last;
  if (first > last) return -1;
  const int height = last - first;
  int tip = -1;
  for (int r = first + static_cast<int>(band_top * height); r <= first + static_cast<int>(band_bottom * height); ++r)
    if (valid(r) && (tip < 0 || front[r] > front[tip])) tip = r;
  return tip;
}

/// The nose root: the deepest point of the concavity above the tip, measured behind the
/// outline's convex hull on the side the face looks to (Andrew's monotone chain over the
/// rows from the silhouette's top to the tip, kept in `hull`): the hull spans the
/// concavity from the brow or forehead to the tip, and the root is the outline point
/// furthest behind it. -1 when that depth is less than `min_feature` of the hull edge
/// spanning it or than `min_feature_px` (a convex outline is not a face).
int find_nose_root(std::span<const float> front, int tip, double min_feature, double min_feature_px,
                   std::vector<int>& hull) {
  // b lies on or behind the chord from a to c (rows a < b < c).
  const auto behind = [&](int a, int b, int c) {
    return (front[b] - front[a]) * static_cast<double>(c - a) <= (front[c] - front[a]) * static_cast<double>(b - a);
  };
  hull.clear();
  for (int r = 0; r <= tip; ++r) {
    if (std::isnan(front[r])) continue;
    while (hull.size() >= 2 && behind(hull[hull.size() - 2], hull.back(), r)) hull.pop_back();
    hull.push_back(r);
  }
  int root = -1;
  double deepest = 0, edge = 0;
  for (std::size_t i = 0; i + 1 < hull.size(); ++i) {
    const int a = hull[i], c = hull[i + 1];
    const double slope = static_cast<double>(front[c] - front[a]) / (c - a);
    for (int r = a + 1; r < c; ++r) {
      if (std::isnan(front[r])) continue;
      const double depth = front[a] + slope * (r - a) - front[r];
      if (depth > deepest) deepest = depth, root = r, edge = std::hypot(c - a, front[c] - front[a]);
    }
  }
  return root >= 0 && deepest >= std::max(min_feature * edge, min_feature_px) ? root : -1;
}

/// Walking down the outline from row `from`: the next extreme point — foremost when
/// `sign` is +1, hindmost when -1 — confirmed once the outline has turned back from it by
/// `prominence` pixels (hysteresis against pixel noise). -1 when the outline ends or has
/// a gap first.
int next_turn(std::span<const float> front, int from, double prominence, int sign) {
  int extreme = from;
  for (int r = from + 1; r < static_cast<int>(front.size()); ++r) {
    if (std::isnan(front[r])) return -1;
    if (sign * front[r] > sign * front[extreme])
      extreme = r;
    else if (sign * (front[extreme] - front[r]) >= prominence)
      return extreme;
  }
  return -1;
}

}  // namespace

SideProfileMeter::SideProfileMeter(const SideProfileSettings& settings) : settings_(settings) {}

SideProfile SideProfileMeter::find(const cv::Mat& gray) {
  if (!gray.empty() && gray.type() != CV_8UC1)
    throw std::invalid_argument("SideProfileMeter: the frame must be 8-bit grey");
  SideProfile profile;
  const cv::Rect frame(0, 0, gray.cols, gray.rows);
  const cv::Rect region = settings_.crop.empty() ? frame : settings_.crop & frame;
  if (region.empty()) return profile;  // kEmptyCrop
  const cv::Mat crop = gray(region);

  profile.status = SideStatus::kNoSilhouette;
  const OtsuSplit split = otsu_split(crop);
  if (split.bright_mean - split.dark_mean < settings_.min_contrast) return profile;
  front_.resize(static_cast<std::size_t>(crop.rows));
  hull_.reserve(front_.size());
  const std::span<float> front(front_);
  const bool bright = face_is_bright(crop, settings_.facing, split);
  scan_front_profile(crop, settings_.facing, face_threshold(split, bright, settings_.background_bias), bright,
                     settings_.min_run, front);

  const auto point = [&](int row) {
    const float x = settings_.facing == ProfileFacing::kRight ? front[row] : crop.cols - 1 - front[row];
    return cv::Point2f(static_cast<float>(region.x) + x, static_cast<float>(region.y + row));
  };
  const int tip = find_nose_tip(front, settings_.nose_band_top, settings_.nose_band_bottom);
  if (tip < 0) return profile;
  profile.status = SideStatus::kNoNose;
  profile.nose_tip = point(tip);
  const int root = find_nose_root(front, tip, settings_.min_feature, settings_.min_feature_px, hull_);
  if (root < 0) return profile;
  profile.nose_root = point(root);
  profile.nose_length_px = std::hypot(tip - root, front[tip] - front[root]);

  // Below the tip: the subnasale concavity, then the upper lip's bump up to the mouth line.
  const double prominence = std::max(settings_.min_feature * profile.nose_length_px, settings_.min_feature_px);
  const int subnasale = next_turn(front, tip, prominence, -1);
  if (subnasale >= 0 && front[tip] - front[subnasale] < prominence) return profile;  // the tip is no bump
  profile.status = SideStatus::kNoLip;
  if (subnasale < 0) return profile;
  profile.subnasale = point(subnasale);
  const int lip = next_turn(front, subnasale, prominence, +1);
  if (lip < 0) return profile;
  profile.upper_lip = point(lip);
  profile.lip_lead_px = front[lip] - front[tip];
  profile.status = SideStatus::kOk;
  return profile;
}

SideMeasure SideProfileMeter::measure(const cv::Mat& gray, const SideReference& reference) {
  SideMeasure m{find(gray)};
  if (!m.ok()) return m;
  if (std::abs(m.profile.nose_length_px / reference.nose_length_px - 1) > settings_.max_nose_change) {
    m.profile.status = SideStatus::kNotTheFace;
    return m;
  }
  m.protrusion = (m.profile.lip_lead_px - reference.lip_lead_px) / reference.nose_length_px;
  return m;
}

SideReference calibrate_side(SideProfileMeter& meter, std::span<const cv::Mat> neutral_frames) {
  std::vector<double> leads, lengths;
  for (const cv::Mat& frame : neutral_frames) {
    const SideProfile profile = meter.find(frame);
    if (!profile.ok()) continue;
    leads.push_back(profile.lip_lead_px);
    lengths.push_back(profile.nose_length_px);
  }
  if (leads.empty())
    throw SideCalibrationError("side calibration: no neutral frame shows a complete profile (nose and upper lip)");
  return {median(leads), median(lengths)};
}

}  // namespace lipdrive
