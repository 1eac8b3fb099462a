// Upper-lip protrusion from the side camera (docs/method.md 4, last bullet): the face in
// profile is segmented from the background (grey -> Otsu threshold on a crop -> the
// foremost face pixel of every row), the profile's landmarks are found along it (nose
// tip, nose root, subnasale, upper lip), and the upper lip's lead over the nose tip is
// compared with the same lead at rest, over the nose root–tip distance. The nose does
// not move with speech and the camera moves with the head, so the nose tip carries the
// reference line fixed at calibration.
//
// Per frame nothing is allocated once the meter has seen a frame of the crop's height:
// the threshold comes from a histogram and the silhouette is a column scan per row, with
// no binary image, contours or connected components.
#pragma once

#include <opencv2/core/mat.hpp>

#include <limits>
#include <span>
#include <stdexcept>
#include <vector>

namespace lipdrive {

/// Which way the face looks in the image.
enum class ProfileFacing { kRight, kLeft };

struct SideProfileSettings {
  ProfileFacing facing = ProfileFacing::kRight;
  /// The part of the frame that holds the profile; empty = the whole frame. It must reach
  /// up to the brow (the nose root is the deepest point below the outline above it) and
  /// down past the mouth, and the face must not reach the crop's edge in front of it: that
  /// column tells the background.
  cv::Rect crop{};
  /// Smallest difference in grey levels between the means of Otsu's two classes; below it
  /// the crop holds no silhouette (a blank or covered camera).
  double min_contrast = 20;
  /// Where the face begins, from Otsu's threshold (0) to the background class's mean (1).
  /// At the outline the skin is seen at a grazing angle and shaded darkest, so Otsu's
  /// level, which splits the mean skin from the background, cuts into the face there.
  double background_bias = 0.5;
  /// Consecutive face pixels a row needs before its foremost one counts (ignores specks).
  int min_run = 3;
  /// The nose tip is sought in this band of the silhouette's rows, from its top (0) to its
  /// bottom (1): above the lips and the chin.
  double nose_band_top = 0.0, nose_band_bottom = 0.65;
  /// Smallest depth of a concavity (nose root, subnasale, mouth line) and height of a
  /// bump, as a fraction of the nose root–tip distance (of the hull edge spanning it for
  /// the nose root), and at least min_feature_px: smaller wiggles of the outline are noise,
  /// and an outline digitised to pixels steps by up to a pixel even where it is convex.
  double min_feature = 0.04;
  double min_feature_px = 2;
  /// The nose root–tip distance may differ from the calibrated one by at most this fraction:
  /// the camera moves with the head and speech does not move the nose, so a profile whose nose
  /// is longer or shorter than that is not the calibrated face (something else in view, or the
  /// camera moved on the rig).
  double max_nose_change = 0.25;
};

enum class SideStatus {
  kOk,
  kEmptyCrop,     // the frame or its crop has no pixels
  kNoSilhouette,  // no contrast between face and background, or no face pixel
  kNoNose,        // no nose tip standing out in front of a nose root
  kNoLip,         // no subnasale below the tip, or no upper lip before the mouth line
  kNotTheFace,    // a complete profile whose nose is not the calibrated one's length (measure())
};

/// The profile of one frame. The points are in frame pixels; each is set once the search
/// got that far (status tells which): tip, root, subnasale, upper lip.
struct SideProfile {
  SideStatus status = SideStatus::kEmptyCrop;
  cv::Point2f nose_tip, nose_root, subnasale, upper_lip;
  double nose_length_px = 0;  // |nose_root - nose_tip|
  double lip_lead_px = 0;     // how far the upper lip is in front of the nose tip (usually < 0)
  bool ok() const { return status == SideStatus::kOk; }
};

/// The reference line, fixed at calibration on the neutral face: where the upper lip is
/// at rest relative to the nose tip, and the nose root–tip distance that normalises.
struct SideReference {
  double lip_lead_px = 0;
  double nose_length_px = 1;
};

struct SideMeasure {
  SideProfile profile;
  /// (lip lead - reference lip lead) / reference nose length: 0 at rest, positive = lips
  /// pushed forward. NaN unless profile.ok().
  double protrusion = std::numeric_limits<double>::quiet_NaN();
  bool ok() const { return profile.ok(); }
};

class SideProfileMeter {
 public:
  explicit SideProfileMeter(const SideProfileSettings& settings = {});

  /// The profile of one grey frame (CV_8UC1; std::invalid_argument otherwise).
  SideProfile find(const cv::Mat& gray);
  /// The protrusion of one grey frame against a calibrated reference; kNotTheFace when the
  /// profile's nose is not the reference's length (settings().max_nose_change).
  SideMeasure measure(const cv::Mat& gray, const SideReference& reference);

  const SideProfileSettings& settings() const { return settings_; }

 private:
  SideProfileSettings settings_;
  std::vector<float> front_;  // per crop row: foremost face position along the facing direction, NaN = none
  std::vector<int> hull_;     // rows of the outline's convex hull above the nose tip
};

/// A neutral capture that cannot calibrate: no frame with a complete profile.
class SideCalibrationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The reference from neutral frames (grey, the performer at rest): the medians
/// (core/statistics.hpp) of the lip lead and the nose length over the frames whose profile
/// is complete. Throws SideCalibrationError when there is none.
SideReference calibrate_side(SideProfileMeter& meter, std::span<const cv::Mat> neutral_frames);

}  // namespace lipdrive
