// The landmark predictor, loaded once per test binary: the Debian model is ~95 MB and
// takes seconds to read, and every tracker in a test can share it.
#pragma once

#include "firmware_app/config/predictor_file.hpp"

#include <memory>

namespace lipdrive::test {

inline std::shared_ptr<const ShapePredictorData> shared_predictor() {
  static const auto data = load_predictor_file(kDefaultPredictorPath);
  return data;
}

}  // namespace lipdrive::test
