#include "core/face_tracker.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>
#include <vector>

namespace lipdrive {

namespace {

/// How many times acquisition moves the box after the landmarks, at most; the change of its
/// turn (radians) and of its place and size (over its width) at which it stops.
constexpr int kSettlePasses = 4;
constexpr double kTurnSettled = std::numbers::pi / 180;
constexpr double kBoxSettled = 0.02;
/// The most pixels the still cascade searches: a larger photograph is reduced to them (a face
/// then needs 40 pixels in the reduced picture). A faceless 12-megapixel picture took 1.1 s and
/// 170 MB more at its own size, 0.14 s and 34 MB reduced.
constexpr double kMaxCascadePixels = 2e6;

/// How far landmark i lies inside the picture's edges (negative beyond them).
double inside(const Landmarks2D& landmarks, int i, int image_width, int image_height) {
  return std::min(
      {landmarks(0, i), image_width - 1 - landmarks(0, i), landmarks(1, i), image_height - 1 - landmarks(1, i)});
}

/// The middle of the outer eye corners.
Eigen::Vector2d eye_centre(const Landmarks2D& p) {
  return 0.5 * (p.col(ibug::kRightEyeOuter) + p.col(ibug::kLeftEyeOuter));
}

/// The face's own axes, so that a tilted head is judged in its own frame: `across` points from
/// the right outer eye corner to the left one (image right for a frontal face), `down` is
/// perpendicular to it (image y grows downwards); both of unit length.
struct FaceAxes {
  Eigen::Vector2d across, down;
};
FaceAxes face_axes(const Landmarks2D& p) {
  const Eigen::Vector2d across = (p.col(ibug::kLeftEyeOuter) - p.col(ibug::kRightEyeOuter)) / interocular_distance(p);
  return {across, Eigen::Vector2d(-across.y(), across.x())};
}

}  // namespace

bool jaw_off_picture(const Landmarks2D& landmarks, int image_width, int image_height, double within) {
  for (int i = ibug::kJawFirst; i <= ibug::kJawLast; ++i)
    if (inside(landmarks, i, image_width, image_height) < within) return true;
  return false;
}

bool plausible_face(const Landmarks2D& landmarks, int image_width, int image_height, double min_interocular_px) {
  if (!landmarks.allFinite()) return false;
  const double iod = interocular_distance(landmarks);
  if (iod < min_interocular_px || iod > image_width) return false;
  // In the picture: the brows, eyes, nose and mouth; the jaw line up to kJawOffPicture beyond
  // it, and then the mouth kMouthInCutPicture inside it.
  bool jaw_cut = false;
  for (int i = 0; i < kNumLandmarks; ++i) {
    const double distance = inside(landmarks, i, image_width, image_height);
    if (distance < (i <= ibug::kJawLast ? -kJawOffPicture * iod : 0)) return false;
    jaw_cut = jaw_cut || distance < 0;
  }
  for (int i = ibug::kMouthCornerRight; jaw_cut && i < kNumLandmarks; ++i)
    if (inside(landmarks, i, image_width, image_height) < kMouthInCutPicture * iod) return false;

  // Depth below the eye line and place across the face, in inter-ocular distances.
  const Eigen::Vector2d eye_mid = eye_centre(landmarks);
  const FaceAxes axes = face_axes(landmarks);
  const auto depth = [&](int i) { return (landmarks.col(i) - eye_mid).dot(axes.down) / iod; };
  const auto lateral = [&](int i) { return (landmarks.col(i) - eye_mid).dot(axes.across) / iod; };
  const double mouth = 0.5 * (depth(ibug::kOuterLipTop) + depth(ibug::kOuterLipBottom));
  // Eye line, nose tip, mouth, chin in this order; chin 0.7..2.2 inter-ocular distances
  // below the eyes (about 1.3 for an adult, more with the mouth wide open).
  if (!(0 < depth(ibug::kNoseTip) && depth(ibug::kNoseTip) < mouth && mouth < depth(ibug::kChin))) return false;
  if (depth(ibug::kChin) < 0.7 || depth(ibug::kChin) > 2.2) return false;
  return lateral(ibug::kMouthCornerRight) < lateral(ibug::kMouthCornerLeft);
}

bool lips_crossed(const Landmarks2D& landmarks) {
  const Eigen::Vector2d down = face_axes(landmarks).down;
  const double iod = interocular_distance(landmarks);
  for (int k = -1; k <= 1; ++k)
    if ((landmarks.col(ibug::kInnerLipBottom - k) - landmarks.col(ibug::kInnerLipTop + k)).dot(down) <
        -kLipsCrossed * iod)
      return true;
  return false;
}

FaceTracker::FaceTracker(std::shared_ptr<const ShapePredictorData> predictor, TrackerSettings settings)
    : settings_(settings), predictor_(predictor), detector_(predictor->detector()) {
  if (settings_.still_cascade) still_cascade_.emplace(*settings_.still_cascade);
}

bool FaceTracker::acquire(const cv::Mat& gray, Landmarks2D& landmarks) {
  if (!still_ && settings_.min_face_px > kDetectorWindowPx) {
    const double reduction = kDetectorWindowPx / settings_.min_face_px;
    cv::resize(gray, resized_, {}, reduction, reduction, cv::INTER_AREA);
    return acquire_among(detector_.detect(resized_), reduction, BoxSource::kDlib, gray, landmarks);
  }
  if (acquire_among(detector_.detect(gray), 1, BoxSource::kDlib, gray, landmarks)) return true;
  if (!still_) return false;
  const double enlargement =
      std::min(2.0, std::sqrt(settings_.max_enlarged_still_pixels / static_cast<double>(gray.total())));
  if (enlargement >= 1.2) {
    cv::resize(gray, resized_, {}, enlargement, enlargement, cv::INTER_LINEAR);
    if (acquire_among(detector_.detect(resized_), enlargement, BoxSource::kDlib, gray, landmarks)) return true;
  }
  if (!still_cascade_) return false;
  const double reduction = std::min(1.0, std::sqrt(kMaxCascadePixels / static_cast<double>(gray.total())));
  if (reduction < 1) cv::resize(gray, resized_, {}, reduction, reduction, cv::INTER_AREA);
  const cv::Mat& searched = reduction < 1 ? resized_ : gray;
  return acquire_among(still_cascade_->detect(searched, kDetectorWindowPx / 2), reduction, BoxSource::kCascade, gray,
                       landmarks);
}

bool FaceTracker::acquire_among(const std::vector<FaceBox>& faces, double scale, BoxSource source, const cv::Mat& gray,
                                Landmarks2D& landmarks) {
  // One performer per camera: of the faces whose landmarks pass the checks, the largest is
  // theirs, measured between its outer eye corners (the detector's boxes come in steps of a
  // fifth, so faces of about one size get the same box). A face whose jaw the picture's edge
  // cuts is taken only when no whole face passes: in a photograph it is a bystander at the
  // edge, larger than the subject. The boxes of an image `scale` times the size of `gray` are
  // scaled back to it.
  struct Candidate {
    FaceBox box;
    Landmarks2D landmarks;
    std::pair<bool, double> rank;  // whole, size
  };
  // A head rolled further than the predictor turns a face from the detector's box: the
  // landmarks are predicted again from the box they give, until its turn settles. Where the box
  // is only roughly placed, until its place settles too: the cascade's (in a face half in
  // shadow the landmarks of the dark half crowd in from it), and any in a camera's frames,
  // whose next frame starts from the landmarks' box anyway (from a box found on a frame reduced
  // by min_face_px, or around glasses, the seven starts can stretch a face to its chin or cross
  // its lips). A still keeps the detector's place: settled, one LFPW still went to another face
  // of its photograph (docs/method.md 1, "Close to the camera").
  const bool settle_place = source == BoxSource::kCascade || !still_;
  std::optional<Candidate> best;
  for (const FaceBox& face : faces) {
    const FaceBox box = {std::lround(face.left / scale), std::lround(face.top / scale), std::lround(face.right / scale),
                         std::lround(face.bottom / scale), face.roll};
    predictor_.predict_median(gray, box, landmarks);  // a detector's box is only roughly placed
    FaceBox last = box;
    for (int pass = 0; pass < kSettlePasses; ++pass) {
      const FaceBox next = predictor_.data()->box_for(landmarks, kUprightRoll);
      const auto shift =
          std::abs(next.width() - last.width()) + std::abs(next.left - last.left) + std::abs(next.top - last.top);
      const bool moved = settle_place && shift > kBoxSettled * static_cast<double>(last.width());
      if (std::abs(next.roll - last.roll) < kTurnSettled && !moved) break;
      last = next;
      predictor_.predict_median(gray, next, landmarks);
    }
    if (!looks_like_a_face(gray, last, landmarks) || lips_crossed(landmarks)) continue;
    if (source == BoxSource::kCascade && !still_cascade_->sees_an_eye(gray, landmarks)) continue;
    const std::pair rank(!jaw_off_picture(landmarks, gray.cols, gray.rows), interocular_distance(landmarks));
    if (!best || rank > best->rank) best = Candidate{box, landmarks, rank};
  }
  if (!best) return false;
  box_ = best->box;
  landmarks = best->landmarks;
  return accept(gray, landmarks, true);
}

bool FaceTracker::looks_like_a_face(const cv::Mat& gray, const FaceBox& box, const Landmarks2D& landmarks) {
  if (predictor_.feature_contrast() < settings_.min_feature_contrast ||
      !plausible_face(landmarks, gray.cols, gray.rows, settings_.min_interocular_px))
    return false;
  const double iod = interocular_distance(landmarks);
  if (!jaw_off_picture(landmarks, gray.cols, gray.rows, kJawOffPicture * iod)) return true;
  predictor_.predict(gray, box, mirrored_, BeyondTheEdge::kMirrored);
  const auto mouth = Eigen::seqN(ibug::kMouthCornerRight, kNumLandmarks - ibug::kMouthCornerRight);
  return (mirrored_(Eigen::all, mouth) - landmarks(Eigen::all, mouth)).colwise().norm().mean() <=
         kMouthMovedBeyondTheEdge * iod;
}

bool FaceTracker::accept(const cv::Mat& gray, const Landmarks2D& landmarks, bool acquiring) {
  if (!acquiring && !looks_like_a_face(gray, box_, landmarks)) return false;
  // The detector found this face: its look is the reference for the frames tracked after it.
  // A face too near the image border for the template is taken once it has moved in.
  if (acquiring || !face_.captured()) {
    face_.capture(gray, landmarks);
    appearance_ = 1;
    face_luma_ = face_.luma();
    // The face found again where the last one was tracked (a head-mounted camera's performer
    // after a cover or a hand) keeps its lower face's look and its lips' luma; another face
    // takes its own.
    if (found_where_last_tracked(landmarks)) {
      look_at_mouth(gray, landmarks);
    } else {
      mouth_look_.capture(gray, landmarks);
      hidden_frames_ = 0;
      settling_frames_ = settings_.settle_mouth_look_frames;
      mouth_ratio_ = 0;
      unlike_lips_frames_ = 0;
    }
    remember_place(landmarks);
    return true;
  }
  const FaceAppearance::Match match = face_.compare(gray, landmarks);
  appearance_ = match.similarity;
  face_luma_ = match.luma;
  if (appearance_ < settings_.min_appearance) return false;
  look_at_mouth(gray, landmarks);
  remember_place(landmarks);
  return true;
}

bool FaceTracker::found_where_last_tracked(const Landmarks2D& landmarks) const {
  if (!(last_interocular_ > 0) || !mouth_look_.captured()) return false;
  const double size = interocular_distance(landmarks) / last_interocular_;
  return (eye_centre(landmarks) - last_eyes_).norm() < 0.5 * last_interocular_ && size > 0.8 && size < 1.25;
}

void FaceTracker::remember_place(const Landmarks2D& landmarks) {
  last_eyes_ = eye_centre(landmarks);
  last_interocular_ = interocular_distance(landmarks);
}

void FaceTracker::look_at_mouth(const cv::Mat& gray, const Landmarks2D& landmarks) {
  // No look of the lower face yet (out of the picture, or flat, at acquisition): take it now.
  if (!mouth_look_.captured()) mouth_look_.capture(gray, landmarks);
  const FaceAppearance::Match match = mouth_look_.compare(gray, landmarks);
  // A lower face the picture's edge cuts (a chin off a close camera's picture) is not judged, nor
  // one without a look (compare() then finds it in no picture).
  const bool hidden = match.in_picture && match.similarity < settings_.min_mouth_appearance;
  hidden_frames_ = hidden ? hidden_frames_ + 1 : 0;
  // A lower face much like the look becomes the look: it follows speech and what changes slowly,
  // not what appears at once. Over a new face's first frames every frame does: a face is often
  // found as something leaves it (a hand lowered, a cover receding).
  const bool settling = settling_frames_ > 0;
  if (settling) --settling_frames_;
  if (settling || match.similarity >= settings_.follow_mouth_appearance ||
      hidden_frames_ >= settings_.new_mouth_look_after) {
    mouth_look_.take(match);  // the grid just compared, not sampled again
    hidden_frames_ = 0;
  }
}

TrackStatus FaceTracker::track(const cv::Mat& gray, Landmarks2D& landmarks) {
  if (tracking_) {
    predictor_.predict(gray, box_, landmarks);
    tracking_ = accept(gray, landmarks, false);
    // Not the face any more: look for it afresh in this same frame.
  }
  const bool acquired = !tracking_ && acquire(gray, landmarks);
  if (!tracking_ && !acquired) return TrackStatus::kNoFace;
  tracking_ = true;
  box_ = predictor_.data()->box_for(landmarks, kUprightRoll);
  return acquired ? TrackStatus::kAcquired : TrackStatus::kTracking;
}

bool FaceTracker::check_mouth(double lip_luma) {
  if (!tracking_ || !(face_luma_ > 0) || !(lip_luma > 0)) return tracking_;
  const double ratio = lip_luma / face_luma_;
  // The lips' luma of a new face; taken afresh, as the lower face's look is, after
  // new_mouth_look_after frames in a row unlike it: lips that stay so are the lips.
  if (mouth_ratio_ == 0 || unlike_lips_frames_ >= settings_.new_mouth_look_after) {
    mouth_ratio_ = ratio;
    unlike_lips_frames_ = 0;
  }
  const double change = ratio > mouth_ratio_ ? ratio / mouth_ratio_ : mouth_ratio_ / ratio;
  const bool unlike = change > settings_.max_mouth_luma_change;
  unlike_lips_frames_ = unlike ? unlike_lips_frames_ + 1 : 0;
  if (ratio < settings_.min_mouth_luma || ratio > settings_.max_mouth_luma || unlike) tracking_ = false;
  return tracking_;
}

bool FaceTracker::check_fit(const Landmarks2D& landmarks, double reprojection_error_px) {
  const bool good = reprojection_error_px <= settings_.max_relative_fit_error * interocular_distance(landmarks);
  if (!good) tracking_ = false;
  return good;
}

}  // namespace lipdrive
