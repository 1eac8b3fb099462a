// iBUG 68-point landmark indices (0-based, as dlib returns them) and the
// landmark sets F1..F5 used for fitting (docs/method.md 1).
#pragma once

#include <Eigen/Core>

#include <array>
#include <optional>
#include <span>
#include <string_view>

namespace lipdrive {

inline constexpr int kNumLandmarks = 68;

/// Column i holds iBUG landmark i in image pixels (x right, y down).
using Landmarks2D = Eigen::Matrix<double, 2, kNumLandmarks>;

namespace ibug {
inline constexpr int kJawFirst = 0, kJawLast = 16;
inline constexpr int kRightBrowFirst = 17, kLeftBrowLast = 26;
inline constexpr int kNoseRoot = 27;  // top of the nose bridge (nasion area)
inline constexpr int kNoseTip = 30;
inline constexpr int kSubnasale = 33;
inline constexpr int kRightEyeOuter = 36, kRightEyeInner = 39;
inline constexpr int kLeftEyeInner = 42, kLeftEyeOuter = 45;
inline constexpr int kMouthCornerRight = 48, kMouthCornerLeft = 54;
inline constexpr int kOuterLipTop = 51, kOuterLipBottom = 57;
inline constexpr int kInnerCornerRight = 60, kInnerCornerLeft = 64;
inline constexpr int kInnerLipTop = 62, kInnerLipBottom = 66;
inline constexpr int kChin = 8;  // gnathion
}  // namespace ibug

/// Outer eye corner to outer eye corner (36-45), the usual face size for normalising errors.
inline double interocular_distance(const Landmarks2D& landmarks) {
  return (landmarks.col(ibug::kLeftEyeOuter) - landmarks.col(ibug::kRightEyeOuter)).norm();
}

enum class LandmarkSet { F1, F2, F3, F4, F5 };
inline constexpr LandmarkSet kDefaultLandmarkSet = LandmarkSet::F4;
/// The sets' names, in LandmarkSet order: what configuration files and the CLI accept.
inline constexpr std::array<std::string_view, 5> kLandmarkSetNames{"F1", "F2", "F3", "F4", "F5"};

/// Number of landmarks in a set: F1 lips (20), F2 +nose (29), F3 +eyes (41),
/// F4 +brows (51), F5 +jaw contour (68).
constexpr int landmark_count(LandmarkSet set) {
  switch (set) {
    case LandmarkSet::F1: return 20;
    case LandmarkSet::F2: return 29;
    case LandmarkSet::F3: return 41;
    case LandmarkSet::F4: return 51;
    case LandmarkSet::F5: return 68;
  }
  return 0;
}

/// The iBUG indices of a set in ascending order.
std::span<const int> landmark_indices(LandmarkSet set);

std::optional<LandmarkSet> parse_landmark_set(std::string_view name);  // "F1".."F5"
std::string_view landmark_set_name(LandmarkSet set);

}  // namespace lipdrive
