// The landmark predictor, loaded once per test binary: the compact file the build converts
// from Debian's dlib model (maps in milliseconds), shared by every tracker in a test.
#pragma once

#include "build_paths.hpp"
#include "firmware_app/config/predictor_file.hpp"

#include <filesystem>
#include <memory>

namespace lipdrive::test {

inline const std::filesystem::path kPredictor = std::filesystem::path(kModelDir) / "face_landmarks.lpp";

inline std::shared_ptr<const ShapePredictorData> shared_predictor() {
  static const auto data = load_predictor_file(kPredictor);
  return data;
}

}  // namespace lipdrive::test
