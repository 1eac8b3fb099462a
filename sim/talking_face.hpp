// A talking face with known ground truth, made from one real photograph: the mouth
// landmarks follow a scripted trajectory (open, spread, round, silence) and a
// piecewise-affine warp on a triangulation of the landmarks moves the pixels with them
// (docs/data-flow.md). The truth is measured on the moved landmarks exactly as the pipeline
// measures the tracked ones (core/mouth_measures.hpp, docs/method.md 4).
#pragma once

#include "core/landmarks.hpp"
#include "core/mouth_measures.hpp"

#include <opencv2/core/mat.hpp>

#include <array>
#include <vector>

namespace lipdrive {

/// Articulation of the mouth, each in [0, 1]: 0 everywhere is the closed neutral mouth.
struct MouthPose {
  double open = 0;    // jaw and lower lip down, inner lips apart
  double spread = 0;  // corners out ("ee")
  double round = 0;   // corners in, lips taller, a small round opening ("oo")
};

/// The script: silences, single vowels and mixed syllables, a little over 8 s;
/// deterministic, one pose per frame at `fps`.
std::vector<MouthPose> scripted_trajectory(double fps);

/// The photo's inner lips moved together (to the midpoints of facing pairs), so the
/// trajectory starts from closed lips even when the photo smiles with teeth showing.
Landmarks2D close_inner_lips(const Landmarks2D& landmarks);

/// The neutral landmarks moved to `pose`. Displacements are proportional to d and follow
/// the face's own axes (eye line), so they hold for any scale and a tilted head.
Landmarks2D pose_mouth(const Landmarks2D& neutral, const MouthPose& pose);

struct TalkingFaceOptions {
  cv::Size frame_size{640, 480};  // what a head-mounted camera delivers
  double face_height_px = 340;    // height of the landmark box (brows to chin) in the frame
};

/// One frame of the clip and its ground truth.
struct TalkingFaceFrame {
  cv::Mat image;          // BGR, TalkingFaceOptions::frame_size
  Landmarks2D landmarks;  // where the face's 68 landmarks are in `image`
  MouthRatios truth;      // mouth_ratios(landmarks): W/d and H/d
};

class TalkingFace {
 public:
  /// `portrait` is 8-bit BGR; `landmarks` are its 68 points in portrait pixels. The face
  /// is cropped around the landmarks and scaled to the frame. Throws std::invalid_argument
  /// when the portrait is empty or the landmarks are degenerate.
  TalkingFace(const cv::Mat& portrait, const Landmarks2D& landmarks, const TalkingFaceOptions& options = {});

  /// The landmarks of the neutral (closed) face in frame pixels.
  const Landmarks2D& neutral_landmarks() const { return neutral_; }
  Landmarks2D landmarks(const MouthPose& pose) const { return pose_mouth(neutral_, pose); }

  /// The frame (BGR) whose face has the given landmarks (from landmarks()).
  cv::Mat render(const Landmarks2D& target) const;
  TalkingFaceFrame frame(const MouthPose& pose) const;

  /// Triangles of the warp as indices into the control points: 0..67 are the landmarks,
  /// the rest fixed anchors on the frame border and around the lower face.
  const std::vector<std::array<int, 3>>& triangles() const { return triangles_; }
  /// Control points of the warp for a target landmark set (landmarks, then the anchors).
  std::vector<cv::Point2d> control_points(const Landmarks2D& target) const;

 private:
  cv::Mat face_;                      // the portrait cropped and scaled to the frame
  Landmarks2D photo_landmarks_;       // the portrait's landmarks in frame pixels
  Landmarks2D neutral_;               // the same with the lips closed
  std::vector<cv::Point2d> anchors_;  // control points that never move
  std::vector<std::array<int, 3>> triangles_;
};

}  // namespace lipdrive
