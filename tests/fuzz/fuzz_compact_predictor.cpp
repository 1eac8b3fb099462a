// Compact landmark predictor files (.lpp): ShapePredictorData::read_compact, which
// load_predictor_file calls on the mapped file, then one prediction on what loads (every
// index it follows was checked).
#include "core/shape_predictor.hpp"

#include <memory>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    auto loaded = std::make_shared<const lipdrive::ShapePredictorData>(
        lipdrive::ShapePredictorData::read_compact({data, size}, nullptr));
    lipdrive::ShapePredictor predictor(loaded);
    const cv::Mat gray(64, 64, CV_8UC1, cv::Scalar(128));
    lipdrive::Landmarks2D landmarks;
    predictor.predict(gray, {8, 8, 55, 55}, landmarks);
  } catch (const lipdrive::ShapePredictorFormatError&) {
  }
  return 0;
}
