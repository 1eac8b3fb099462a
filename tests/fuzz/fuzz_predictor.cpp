// Landmark predictor files (dlib's shape_predictor serialisation): ShapePredictorData::read_dlib,
// which load_predictor_file calls on a .dat file.
#include "core/shape_predictor.hpp"

#include <sstream>
#include <string>

namespace {

// Decoded once: it is not what is fuzzed, and decoding it takes a second.
lipdrive::FaceDetector builtin_once() {
  static const lipdrive::FaceDetector detector = lipdrive::FaceDetector::builtin();
  return detector;
}

}  // namespace

// Decoded before the first input: under ASan on a loaded machine the decode alone took more
// than the 10 s that fuzz.sh allows one input, and failed the run on the first seed.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  builtin_once();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    lipdrive::ShapePredictorData::read_dlib(in, &builtin_once);
  } catch (const lipdrive::ShapePredictorFormatError&) {
  }
  return 0;
}
