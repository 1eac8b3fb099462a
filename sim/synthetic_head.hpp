// The built-in head: a face mesh and its viseme poses, generated deterministically
// (docs/method.md 2: neutral + 16 visemes x 10 intensities).
#pragma once

#include "core/drive_signals.hpp"  // kVisemeNames
#include "core/landmarks.hpp"
#include "core/morphable_model.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

struct HeadPose {
  std::string name;
  Eigen::Matrix3Xf vertices;  // same vertex order for all poses
};

enum class HeadPoseSet { Full161, FullIntensity17 };

struct SyntheticHead {
  std::vector<Triangle> triangles;
  std::array<std::int32_t, kNumLandmarks> landmark_vertex;  // all 68 iBUG points, distinct vertices
  std::vector<HeadPose> poses;  // "neutral" first, then "<viseme>_<percent>", e.g. "BigAah_030"
};

/// Full161: neutral + 16 visemes x 10 intensities (010..100);
/// FullIntensity17: neutral + 16 visemes at 100.
/// Model space: millimetres, x towards the subject's left, y up, z out of the face;
/// the nasion is the origin.
SyntheticHead generate_synthetic_head(HeadPoseSet set);

}  // namespace lipdrive
