// Landmark predictor files: lipdrive's compact .lpp (mapped in place, with its face detector;
// core/shape_predictor.hpp has the layout), or any dlib shape predictor (.dat) that predicts
// the 68 iBUG landmarks, e.g. Debian's (research-only licence, see core/face_tracker.hpp) or
// a user-trained one. `lipdrive predictor convert` turns a .dat into an .lpp; the build does
// it for Debian's. And the face cascade the offline commands search stills with when dlib's
// detector finds no face in them.
#pragma once

#include "core/shape_predictor.hpp"
#include "firmware_app/config/paths.hpp"

#include <filesystem>
#include <memory>

namespace lipdrive {

/// Reads a predictor file, an .lpp (told by its header) or a dlib .dat. Throws CommandError
/// naming the path: kExitNoInput when it is missing or unreadable, kExitDataError when it is
/// not a 68-point predictor.
std::shared_ptr<const ShapePredictorData> load_predictor_file(const std::filesystem::path& path);

/// The face and eye cascades for stills in `face` and `eye`. Either missing: a warning that
/// stills are searched by dlib's detector alone, and nullptr. Throws CommandError naming the
/// path when one cannot be read (kExitNoInput) or holds no cascade (kExitDataError).
std::shared_ptr<const CascadeFaceDetector> load_still_cascade(
    const std::filesystem::path& face = kOpenCvFaceCascadePath,
    const std::filesystem::path& eye = kOpenCvEyeCascadePath);

/// Writes `predictor` as an .lpp file (replace_file: never half-written).
void save_compact_predictor_file(const std::filesystem::path& path, const ShapePredictorData& predictor);

}  // namespace lipdrive
