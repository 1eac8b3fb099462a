// FaceTracker: 68 iBUG landmarks per frame from a head-mounted camera (docs/data-flow.md).
//
// dlib's HOG frontal face detector runs only to acquire a face (first frame, or after the
// track was lost): it costs tens of milliseconds and allocates. While tracking, the box
// comes from the previous frame's landmarks (the camera moves with the head, so the face
// stays in place; the box turns with a head rolled beyond kUprightRoll) and only the shape
// predictor runs, which allocates nothing. A detector's box is only roughly placed, so an
// acquired face's landmarks are the median of seven predictions from boxes around it
// (ShapePredictor::predict_median, docs/method.md 1). A still photograph in which the detector
// finds no face is searched again at twice its size, then by OpenCV's face cascade
// (TrackerSettings::still_cascade); a camera's frames never are.
//
// Every tracked frame is validated as the face that was acquired; the predictor returns 68
// points wherever its box is, so after a cut, a face leaving the frame or a hand over the
// lens it would follow whatever is there. The track is dropped when the landmarks are
// implausible (outside the image, but for a jaw line the picture's edge cuts a little; a
// degenerate face size or aspect; eyes/nose/mouth out of order; with the jaw at the edge, a
// mouth that moves when the picture is mirrored beyond it), when the predictor's feature
// pixels have no contrast (a blank or covered frame), when the upper face around them no
// longer looks like the one the detector acquired
// (core/face_check.hpp: normalised correlation of a luma grid, a few microseconds), when the
// caller's 3DMM fit cannot explain them (check_fit), or when the lips turn much darker or
// brighter than the face (check_mouth: something over the mouth). A frame that fails the
// first three runs the detector at once, so a cut to a face elsewhere loses no frame; after
// the last two the next frame does. A lower face that no longer looks like the track's
// (a hand, a card before the mouth) keeps the track but hides the mouth (mouth_hidden).
//
// Licence: the Debian predictor /usr/share/dlib/shape_predictor_68_face_landmarks.dat is
// trained on the iBUG 300-W data set, whose licence excludes commercial use; a product
// must ship a predictor trained on data it may use (any 68-point dlib .dat drops in).
#pragma once

#include "core/face_check.hpp"
#include "core/landmarks.hpp"
#include "core/shape_predictor.hpp"

#include <opencv2/core/mat.hpp>

#include <memory>
#include <numbers>
#include <optional>

namespace lipdrive {

/// The width of dlib's HOG detector window: the smallest face it finds at an image's own size.
inline constexpr double kDetectorWindowPx = 80;

struct TrackerSettings {
  /// Fit RMS reprojection error over inter-ocular distance above which the landmarks are
  /// taken not to be a face.
  double max_relative_fit_error = 0.12;
  /// Below this standard deviation (grey levels) of the feature pixels the box holds no face.
  double min_feature_contrast = 3.0;
  /// Smallest inter-ocular distance in pixels the predictor is trusted at.
  double min_interocular_px = 12.0;
  /// Below this normalised correlation with the upper face seen at acquisition
  /// (FaceAppearance) the landmarks are no longer on that face.
  double min_appearance = 0.5;
  /// The lips' luma over the upper face's (FaceAppearance::luma) lies in this range on every
  /// face seen so far (0.54..1.45 over the 58 LFPW photographs, 0.71..0.86 over the GRID
  /// clips) and may change by at most max_mouth_luma_change from the first frame of the face's
  /// track (either way; a face found again where it was tracked keeps it, for at most
  /// `new_mouth_look_after` such frames in a row): anything else is a hand or an object over
  /// the mouth.
  double min_mouth_luma = 0.4, max_mouth_luma = 2.0;
  double max_mouth_luma_change = 1.5;
  /// Below this normalised correlation of the lower face (FaceRegion::kLowerFace) with its look,
  /// something is before the mouth (mouth_hidden). The look is taken when a new face is acquired
  /// (a face found again where the last was tracked keeps it), from every frame of its first
  /// `settle_mouth_look_frames`, and then from every frame at least `follow_mouth_appearance`
  /// like it: speech and slow changes, not a hand raised. A talking face keeps its lower face
  /// above 0.51 of its first look over the 52 GRID clips, above 0.41 on the generated one; a
  /// hand or a card before the mouth reads under 0.3 in most frames (docs/method.md 1,
  /// "Something over the mouth"). After `new_mouth_look_after` hidden frames in a row the look
  /// is taken afresh: a track that began with a hand before the mouth would otherwise never
  /// measure it.
  double min_mouth_appearance = 0.3;
  double follow_mouth_appearance = 0.7;
  int settle_mouth_look_frames = 10;
  int new_mouth_look_after = 50;
  /// The narrowest face box, in pixels, a camera's frames are searched for. dlib's detector
  /// slides an 80-pixel window (kDetectorWindowPx) and finds faces from about that size up; a
  /// camera whose face is always larger (a head-mounted rig's fills the picture) lets it search
  /// the frame reduced by kDetectorWindowPx / min_face_px, at that factor squared of the cost.
  /// Stills are searched at their own size (and twice it) whatever this says.
  double min_face_px = kDetectorWindowPx;
  /// The most pixels a still without a face at its own size is enlarged to for a second search
  /// (FaceTracker::reset); an enlargement under 1.2 is not worth one.
  double max_enlarged_still_pixels = 16e6;
  /// A still in which dlib's detector finds no face, at its own size or enlarged, is searched
  /// by this one (a copy of it: CascadeFaceDetector) for faces from half dlib's window wide;
  /// none: not searched further. A camera's frames never are (docs/method.md 1, "A face the
  /// HOG detector misses").
  std::shared_ptr<const CascadeFaceDetector> still_cascade{};
};

enum class TrackStatus {
  kAcquired,  // detected in this frame
  kTracking,  // followed from the previous frame
  kNoFace,    // no face: landmarks are not valid
};

/// How far the jaw line (landmarks 0-16) may lie beyond the picture's edge, in inter-ocular
/// distances. A camera framed close cuts the chin when the mouth opens wide, or the side of the
/// jaw when the head turns; the predictor then puts the cut jaw at the edge or just beyond it
/// (docs/method.md 1, "A jaw the picture cuts"). Up to this much beyond, the mouth is as
/// accurate as in the whole picture; the rest of the face must be inside.
inline constexpr double kJawOffPicture = 0.07;
/// With the jaw line beyond the edge, how far inside it the mouth (landmarks 48-67) must be,
/// in inter-ocular distances: an edge nearer the lips than this misplaces them.
inline constexpr double kMouthInCutPicture = 0.15;

/// With the jaw line at the picture's edge (within kJawOffPicture of it, or beyond), how far
/// the mouth (landmarks 48-67, mean, in inter-ocular distances) may move when the predictor
/// sees the picture mirrored beyond the edge instead of black. A picture that cuts through the
/// mouth leaves the predictor free to draw the whole lower face up into it, the mouth about
/// 0.3 inter-ocular distances from the lips; what lies beyond the edge then decides where the
/// mouth goes (docs/method.md 1, "A picture that cuts through the mouth"). The bound is the
/// false-track bound of every tracked frame.
inline constexpr double kMouthMovedBeyondTheEdge = 0.1;
/// How far the inner lips may cross, in inter-ocular distances along the face's vertical, for a
/// face to be acquired: the upper inner lip (61-63) below the lower one (67-65). Over a flat card
/// held in front of the mouth the predictor turns the mouth over, 0.08-0.18; the landmarks of
/// real mouths cross by 0.012 at most over the 58 LFPW photographs and never over the 3,888
/// tracked frames of the GRID clips, but by up to 0.078 under a moustache that hides the upper
/// lip, the face swaying a little (docs/method.md 1, "Something over the mouth"). So the bound
/// keeps a card from being acquired as a mouth; once a face is tracked, the lower face's look
/// judges what is before its mouth (it hides every frame of a card the bound dropped), and
/// crossed lips are its lips.
inline constexpr double kLipsCrossed = 0.04;
/// How far a face may roll in the picture (radians either way) for the shape predictor to
/// find its landmarks from an upright box, as dlib's detector gives and its training used: at
/// 10 and 20 degrees the mouth lies within 0.01 inter-ocular distances of where it is in the
/// same picture upright, at 30 degrees 0.10 off. A face rolled further is predicted in a box
/// turned by the excess (docs/method.md 1, "A rolled head").
inline constexpr double kUprightRoll = 10 * std::numbers::pi / 180;

/// Whether a point of the jaw line (0-16) lies beyond the picture's edge, or less than
/// `within` pixels inside it.
bool jaw_off_picture(const Landmarks2D& landmarks, int image_width, int image_height, double within = 0);

/// The geometric sanity checks the tracker applies to every frame's landmarks.
bool plausible_face(const Landmarks2D& landmarks, int image_width, int image_height, double min_interocular_px);

/// Whether the inner lips cross by more than kLipsCrossed, column by column (61 over 67, 62 over
/// 66, 63 over 65): checked on a face about to be acquired.
bool lips_crossed(const Landmarks2D& landmarks);

class FaceTracker {
 public:
  explicit FaceTracker(std::shared_ptr<const ShapePredictorData> predictor, TrackerSettings settings = {});

  /// Landmarks of the face in the luma image `gray` (CV_8UC1). A tracked face whose new
  /// landmarks fail the checks is looked for afresh by the detector in the same frame. When
  /// the result is kNoFace, `landmarks` is unspecified and the next call runs the detector.
  TrackStatus track(const cv::Mat& gray, Landmarks2D& landmarks);

  /// Feeds back the 3DMM fit of the landmarks track() returned: a fit error above
  /// max_relative_fit_error drops the track. Returns whether the frame is accepted.
  bool check_fit(const Landmarks2D& landmarks, double reprojection_error_px);

  bool tracking() const { return tracking_; }

  /// What follows a reset: frames of a camera or a video, or a still photograph.
  enum class Next { kVideo, kStill };
  /// Drops the track: the next frame runs the detector (an unrelated frame follows). Before a
  /// still photograph the detector, finding no face at the image's own size, looks again at
  /// twice it: its 80-pixel window then finds faces from about 20 pixels between the outer eye
  /// corners instead of about 40 (as dlib's own examples enlarge photographs once). It costs
  /// four times the detection, on stills without a face only; a camera's frames never pay it.
  /// The enlarged image is at most TrackerSettings::max_enlarged_still_pixels (by default a
  /// photograph over 4 megapixels is enlarged less, one over 11 not at all): enlarging a
  /// 12-megapixel photograph twice took 4.9 s and 510 MB to find no face, and a face that
  /// small in it is too few pixels for its mouth to be measured. Where neither search finds a
  /// face, TrackerSettings::still_cascade looks for one.
  void reset(Next next) {
    tracking_ = false;
    still_ = next == Next::kStill;
    last_interocular_ = 0;
  }
  /// Feeds back the lips' luma the caller measured on the landmarks track() returned
  /// (LipGap::lip_luma): a mouth much darker or brighter, relative to the upper face, than at
  /// the start of the face's track drops it (TrackerSettings::max_mouth_luma_change). Returns
  /// whether the frame is accepted.
  bool check_mouth(double lip_luma);

  /// While a face is tracked, ShapePredictor::warm(): the predictor data the next frame will
  /// most likely read, into the cache. Returns whether it did (a face is tracked). Allocates
  /// nothing.
  bool warm() const {
    if (tracking_) predictor_.warm();
    return tracking_;
  }

  /// FaceAppearance similarity of the last tracked frame (1 on acquisition).
  double appearance() const { return appearance_; }
  /// Whether something is before the mouth in the last tracked frame: the lower face looks
  /// unlike the track's (TrackerSettings::min_mouth_appearance). The face is still tracked (its
  /// box follows it), but its mouth's landmarks are not the mouth's.
  bool mouth_hidden() const { return hidden_frames_ > 0; }

 private:
  bool acquire(const cv::Mat& gray, Landmarks2D& landmarks);
  /// Which detector gave a box: dlib's, whose boxes the predictor was trained on, or the still
  /// cascade, whose boxes are only roughly where dlib's would be.
  enum class BoxSource { kDlib, kCascade };
  bool acquire_among(const std::vector<FaceBox>& faces, double scale, BoxSource source, const cv::Mat& gray,
                     Landmarks2D& landmarks);
  /// The last prediction, from `box`, gave landmarks with a face's layout and feature pixels
  /// with contrast, and (the jaw line at the picture's edge) a mouth that stays where it is
  /// when the predictor sees the picture mirrored beyond the edge (kMouthMovedBeyondTheEdge;
  /// that prediction is then the predictor's last, whose leaves warm() reads).
  bool looks_like_a_face(const cv::Mat& gray, const FaceBox& box, const Landmarks2D& landmarks);
  /// Whether the landmarks are the face: on acquisition (already checked) its look becomes
  /// the reference; while tracking they must look like a face and like that reference.
  bool accept(const cv::Mat& gray, const Landmarks2D& landmarks, bool acquiring);
  /// Compares the lower face with the track's look of it: counts the hidden frames.
  void look_at_mouth(const cv::Mat& gray, const Landmarks2D& landmarks);
  /// Whether a face just acquired is where the last accepted frame's was: its eye centre within
  /// half an inter-ocular distance, its size within 25 %.
  bool found_where_last_tracked(const Landmarks2D& landmarks) const;
  void remember_place(const Landmarks2D& landmarks);

  TrackerSettings settings_;
  ShapePredictor predictor_;
  FaceDetector detector_;  // a copy of the predictor's
  std::optional<CascadeFaceDetector> still_cascade_;  // a copy of the settings'
  FaceAppearance face_;
  FaceAppearance mouth_look_{FaceRegion::kLowerFace};
  double appearance_ = 0;
  int hidden_frames_ = 0;    // tracked frames in a row with the mouth hidden (0: not hidden)
  int settling_frames_ = 0;  // frames left in which every frame becomes the lower face's look
  Eigen::Vector2d last_eyes_ = Eigen::Vector2d::Zero();  // the last accepted frame's eye centre
  double last_interocular_ = 0;                          // and inter-ocular distance; 0 = none
  double face_luma_ = 0;    // this frame's upper-face luma
  double mouth_ratio_ = 0;  // lips over upper face at the start of the face's track; 0 = not yet seen
  int unlike_lips_frames_ = 0;  // frames in a row whose lips' luma changed too far from it
  bool still_ = false;      // the frame after reset(Next::kStill) is a still photograph
  cv::Mat resized_;         // the frame the detector searches when not at its own size
  FaceBox box_;             // where the next tracked frame looks: derived from the last landmarks
  Landmarks2D mirrored_;    // looks_like_a_face's prediction with the picture mirrored beyond its edge
  bool tracking_ = false;
};

}  // namespace lipdrive
