// A camera mounted on its side or upside down (a head rig's camera turned so that the face's
// height fills the sensor's width): its frames turned upright before anything looks at them.
#pragma once

#include <opencv2/core/mat.hpp>

#include <optional>

namespace lipdrive {

/// The clockwise quarter turn that stands a camera's frame upright.
enum class Rotation { k0 = 0, k90 = 90, k180 = 180, k270 = 270 };

/// The rotation of `degrees` clockwise; nullopt unless 0, 90, 180 or 270.
std::optional<Rotation> rotation_from_degrees(int degrees);

/// `in` (an 8-bit plane) turned clockwise by `rotation` into `out`, which must not share its
/// memory: a copy for k0; an empty `in` (a monochrome camera's missing chroma) leaves `out`
/// empty. `out` keeps its buffer while the frame size stays the same, so a stream of frames
/// allocates once.
void rotate_plane(const cv::Mat& in, cv::Mat& out, Rotation rotation);

}  // namespace lipdrive
