// The per-frame step shared by `lipdrive process` and the daemon's pipeline:
// landmarks -> 3DMM fit -> mouth measures (DESIGN.md 2), and the CSV row both write.
#pragma once

#include "core/face_tracker.hpp"
#include "core/fitting.hpp"
#include "core/mouth_measures.hpp"
#include "core/viseme_weights.hpp"

#include <fmt/format.h>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace lipdrive {

struct FrameMeasurement {
  bool tracked = false;    // a face was tracked and the fit explains it: `measures` is valid
  MouthMeasures measures;
  VisemeWeights visemes{};  // valid when `tracked`; all zero when the model has no viseme poses
  Landmarks2D landmarks;   // the tracked landmarks, valid when `tracked`
  // Time spent in each stage (ms); NaN when the stage did not run for this frame.
  double landmarks_ms = 0, fit_ms = 0, measures_ms = 0;
};

class FrameProcessor {
 public:
  /// Throws std::invalid_argument when the model cannot be fitted with `set` (see Fitter).
  FrameProcessor(const MorphableModel& model, LandmarkSet set, FitSettings settings,
                 std::shared_ptr<const ShapePredictorData> predictor);

  /// Measures one luma frame (CV_8UC1). Allocation-free while the face stays tracked
  /// (acquiring it runs dlib's detector, which allocates).
  const FrameMeasurement& process(const cv::Mat& gray);

 private:
  Fitter fitter_;
  LandmarkSet set_;  // the landmarks the fit and the viseme pose match use
  MouthReference reference_;
  std::optional<VisemeSolver> visemes_;  // nullopt: the model lacks the viseme poses
  FaceTracker tracker_;
  FitOutput fit_ = Fitter::initial_output();  // warm start of the next frame
  FrameMeasurement result_;
};

/// Where a CSV row's frame came from.
struct CsvRowKey {
  std::uint64_t frame = 0;
  double time_s = 0;
  std::string_view source;
};

/// The column names of `lipdrive process` output, without the line end: the measures, then
/// viseme_Aah..viseme_W; with `include_landmarks`, x0..x67,y0..y67 follow.
std::string measures_csv_header(bool include_landmarks);

/// One row under measures_csv_header, without the line end. `measures` null: the frame was
/// not tracked (empty fields; `visemes` is not read). `landmarks` null: no landmark columns.
void append_measures_csv_row(fmt::memory_buffer& row, const CsvRowKey& key, const MouthMeasures* measures,
                             std::span<const float, kNumVisemes> visemes, const Landmarks2D* landmarks);

}  // namespace lipdrive
