// Landmark predictor files: any dlib shape predictor (.dat) that predicts the 68 iBUG
// landmarks, e.g. Debian's (research-only licence, see core/face_tracker.hpp) or a
// user-trained one.
#pragma once

#include "core/shape_predictor.hpp"
#include "firmware_app/config/paths.hpp"

#include <filesystem>
#include <memory>

namespace lipdrive {

/// Reads a predictor file. Throws CommandError naming the path: kExitNoInput when it is
/// missing or unreadable, kExitDataError when it is not a 68-point dlib shape predictor.
std::shared_ptr<const ShapePredictorData> load_predictor_file(const std::filesystem::path& path);

}  // namespace lipdrive
