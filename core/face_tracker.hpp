// FaceTracker: 68 iBUG landmarks per frame from a head-mounted camera (docs/data-flow.md).
//
// dlib's HOG frontal face detector runs only to acquire a face (first frame, or after the
// track was lost): it costs tens of milliseconds and allocates. While tracking, the box
// comes from the previous frame's landmarks (the camera moves with the head, so the face
// stays in place) and only the shape predictor runs, which allocates nothing.
//
// The track is dropped, and the next frame re-detects, when the landmarks are implausible
// (outside the image, a degenerate face size or aspect, eyes/nose/mouth out of order), when
// the predictor's feature pixels have no contrast (a blank or covered frame), or when the
// caller's 3DMM fit cannot explain them (check_fit).
//
// Licence: the Debian predictor /usr/share/dlib/shape_predictor_68_face_landmarks.dat is
// trained on the iBUG 300-W data set, whose licence excludes commercial use; a product
// must ship a predictor trained on data it may use (any 68-point dlib .dat drops in).
#pragma once

#include "core/landmarks.hpp"
#include "core/shape_predictor.hpp"

#include <opencv2/core/mat.hpp>

#include <memory>

namespace lipdrive {

struct TrackerSettings {
  /// Fit RMS reprojection error over inter-ocular distance above which the landmarks are
  /// taken not to be a face.
  double max_relative_fit_error = 0.12;
  /// Below this standard deviation (grey levels) of the feature pixels the box holds no face.
  double min_feature_contrast = 3.0;
  /// Smallest inter-ocular distance in pixels the predictor is trusted at.
  double min_interocular_px = 12.0;
};

enum class TrackStatus {
  kAcquired,  // detected in this frame
  kTracking,  // followed from the previous frame
  kNoFace,    // no face: landmarks are not valid
};

/// Outer eye corner to outer eye corner (36-45), the usual face size for normalising errors.
double interocular_distance(const Landmarks2D& landmarks);

/// The geometric sanity checks the tracker applies to every frame's landmarks.
bool plausible_face(const Landmarks2D& landmarks, int image_width, int image_height, double min_interocular_px);

class FaceTracker {
 public:
  explicit FaceTracker(std::shared_ptr<const ShapePredictorData> predictor, TrackerSettings settings = {});
  ~FaceTracker();
  FaceTracker(FaceTracker&&) noexcept;
  FaceTracker& operator=(FaceTracker&&) noexcept;

  /// Landmarks of the face in the luma image `gray` (CV_8UC1). When the result is
  /// kNoFace, `landmarks` is unspecified and the next call runs the detector.
  TrackStatus track(const cv::Mat& gray, Landmarks2D& landmarks);

  /// Feeds back the 3DMM fit of the landmarks track() returned: a fit error above
  /// max_relative_fit_error drops the track. Returns whether the frame is accepted.
  bool check_fit(const Landmarks2D& landmarks, double reprojection_error_px);

  bool tracking() const { return tracking_; }

 private:
  struct Detector;  // dlib's frontal_face_detector, kept out of this header
  bool detect(const cv::Mat& gray);
  bool accept(const cv::Mat& gray, const Landmarks2D& landmarks);

  TrackerSettings settings_;
  ShapePredictor predictor_;
  std::unique_ptr<Detector> detector_;
  FaceBox box_;  // where the next tracked frame looks: derived from the last landmarks
  bool tracking_ = false;
};

}  // namespace lipdrive
