// A recording named on the command line (a video, an image or a folder of images), opened as
// the offline commands play it: the simulated camera, as fast as possible, once through.
#pragma once

#include "sim/simulated_camera.hpp"

#include <filesystem>

namespace lipdrive {

/// Throws CommandError naming the path: missing or unreadable (exit 66), or not a recording
/// (exit 65).
SimulatedCamera open_recording(const std::filesystem::path& input);

}  // namespace lipdrive
