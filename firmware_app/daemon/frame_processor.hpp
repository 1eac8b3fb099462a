// The per-frame step shared by `lipdrive process`, `lipdrive calibrate` and the daemon's
// processing thread: landmarks -> 3DMM fit -> mouth measures and viseme weights (docs/data-flow.md),
// on fixed-size data. config/factories.hpp builds it from a configuration.
#pragma once

#include "core/arkit.hpp"
#include "core/drive_signals.hpp"
#include "core/face_tracker.hpp"
#include "core/fitting.hpp"
#include "core/mouth_measures.hpp"
#include "core/viseme_weights.hpp"

#include <opencv2/core/mat.hpp>

#include <memory>
#include <optional>
#include <span>
#include <vector>

namespace lipdrive {

struct FrameMeasurement {
  bool tracked = false;  // a face was tracked and the fit explains it: `measures` is valid
  MouthMeasures measures;
  VisemeWeights visemes{};  // valid when `tracked`; all zero for a model without expression shapes or viseme poses
  Landmarks2D landmarks;    // the tracked landmarks, valid when `tracked`
  double appearance = 0;    // FaceTracker::appearance() of this frame
  // Time spent in each stage (ms); NaN when the stage did not run for this frame.
  double landmarks_ms = 0, fit_ms = 0, measures_ms = 0;
};

/// Without a calibrated identity, a model with expression shapes can fit one itself: from its
/// first `frames` tracked frames, taken as neutral as `lipdrive calibrate` takes its first ones,
/// the identity and its rest point as calibration fits them (docs/arkit.md, "Without a
/// calibration"). Until then the fit runs on a provisional identity and rest point, the first
/// frame's alone, and the expression weights read 0.
struct AutoIdentity {
  std::shared_ptr<const MorphableModel> model;  // the processor's model, kept for the one-time fit
  int frames = 0;                               // 0 = off: the mean face until calibrated
};

class FrameProcessor {
 public:
  /// Throws std::invalid_argument when the model cannot be fitted with `set` (see Fitter).
  /// `identity`: the performer's, for a model with expression shapes (PerformerIdentity; empty =
  /// the mean face), `rest` its rest point (PerformerIdentity::rest_weights; zero = none): the
  /// ARKit weights and the visemes made from them are the fit's weights above_rest().
  /// `automatic`: with an empty identity and a model with expression shapes, fit one (AutoIdentity).
  /// `tracking`: the face tracker's (`[tracker] min_face_px`).
  FrameProcessor(const MorphableModel& model, LandmarkSet set, FitSettings settings,
                 std::shared_ptr<const ShapePredictorData> predictor,
                 const Eigen::VectorXf& identity = Eigen::VectorXf(),
                 const FitOutput::Expressions& rest = FitOutput::Expressions::Zero(), AutoIdentity automatic = {},
                 TrackerSettings tracking = {});

  /// Measures one frame: its luma (CV_8UC1) and, from a colour camera, its Cr plane (CV_8UC1,
  /// empty otherwise: the lip contact then reads the luma alone). Allocation-free while the face stays tracked
  /// (acquiring it runs dlib's detector, which allocates; so does the one frame on which an
  /// AutoIdentity is fitted, and the first of its frames, which fits the provisional one).
  const FrameMeasurement& process(const cv::Mat& gray, const cv::Mat& cr);

  /// The next frame is unrelated to the last (a still photograph, or the first frame of
  /// another clip): detect afresh (FaceTracker::reset), and gather an AutoIdentity's frames
  /// afresh (another image may be another face). Before a still an AutoIdentity also starts
  /// again from the mean face, so that each photograph is measured as it would be alone, not
  /// on the identity fitted on the one before it.
  void forget(FaceTracker::Next next);

  /// Before the next frame is due: the landmark predictor's data into the cache
  /// (FaceTracker::warm; false while no face is tracked). Allocates nothing.
  bool warm() const { return tracker_.warm(); }

  /// Whether an AutoIdentity is still gathering its frames (the fit is on the mean face, then
  /// on the provisional identity, and the expression weights read 0).
  bool identity_pending() const { return automatic_.frames > 0; }

  /// The identity the next frame is fitted on (a model with expression shapes; empty: the mean
  /// face). An AutoIdentity changes it after the frame that completes (or starts) its frames.
  const Eigen::VectorXf& identity() const { return identity_; }

  /// The last fit; its projected landmarks are the fitted model's in the last frame when that
  /// frame was tracked.
  const FitOutput& fit() const { return fit_; }

  /// The 52 ARKit signals of the last frame into `signals`, which holds its other signals
  /// (core/arkit.hpp: from the fit when the model has expression shapes, else from the signals).
  /// Call only when that frame was tracked. Allocates nothing.
  void set_arkit(DriveSignals& signals) const {
    set_arkit_signals(arkit_, std::span<const double>(above_rest_.data(), above_rest_.size()), signals);
  }

 private:
  void gather_identity_frame(const Landmarks2D& landmarks);
  /// The fitter and the mouth reference on identity_ and rest_; the next fit starts afresh.
  void fit_on_identity(const MorphableModel& model);

  LandmarkSet set_;
  FitSettings settings_;
  const AutoIdentity first_automatic_;        // as constructed: what a still starts from again
  const FitOutput::Expressions first_rest_;
  AutoIdentity automatic_;                    // frames = 0 once fitted, or when off
  std::vector<Landmarks2D> identity_frames_;  // reserved for automatic_.frames
  Eigen::VectorXf identity_;
  Fitter fitter_;
  ArkitMap arkit_;
  MouthReference reference_;
  std::optional<VisemeSolver> visemes_;  // the pose match; nullopt: the model lacks the viseme poses
  FaceTracker tracker_;
  FitOutput fit_ = Fitter::initial_output();  // warm start of the next frame
  bool fit_afresh_ = false;                   // the identity changed: the next frame starts from initial_output()
  FitOutput::Expressions rest_;               // the performer's rest point
  FitOutput::Expressions above_rest_ = FitOutput::Expressions::Zero();  // the last fit's weights above it
  FrameMeasurement result_;
};

}  // namespace lipdrive
