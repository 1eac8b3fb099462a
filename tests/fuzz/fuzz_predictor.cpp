// Landmark predictor files (dlib's shape_predictor serialisation): ShapePredictorData::read_dlib,
// which load_predictor_file calls on the file.
#include "core/shape_predictor.hpp"

#include <sstream>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    lipdrive::ShapePredictorData::read_dlib(in);
  } catch (const lipdrive::ShapePredictorFormatError&) {
  }
  return 0;
}
