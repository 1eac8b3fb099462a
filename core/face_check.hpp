// Is a tracked frame still the face that was acquired? (DESIGN.md 2, "every tracked frame
// validated as a face")
//
// The shape predictor always returns 68 points, wherever its box is: after a cut to another
// shot, a face that left the frame or a hand over the lens it converges on whatever is
// there, and the geometric checks pass as long as the points keep a face's layout. What the
// points cannot fake is the look of the face around them. When the detector acquires a face,
// FaceAppearance samples a small grid of luma values over the upper face (brows, eyes, nose:
// the parts speech does not move) in the face's own frame, set by the eye and nose landmarks;
// every tracked frame samples the same grid at its own landmarks and compares it with that
// template by normalised correlation, which ignores gain and offset (lighting, exposure).
// A sample is the mean of four bilinear taps around it, so the grid does not alias on a
// large face. About 500 taps: a few microseconds.
//
// The same grid over the lower face (from the nose tip to below the lower lip, still in the frame
// the eyes and nose set) tells whether something is before the mouth: a hand, a card, a microphone's
// windscreen hide the lips, and the predictor puts a mouth on them all the same. Speech moves
// the lower face, but not so far from the same face's look that a cover is nearer to it
// (docs/method.md 1, "Something over the mouth").
#pragma once

#include "core/landmarks.hpp"

#include <opencv2/core/mat.hpp>

#include <array>

namespace lipdrive {

/// The part of the face a FaceAppearance samples.
enum class FaceRegion {
  kUpperFace,  // brows, eyes, nose: what speech does not move
  kLowerFace,  // from the nose tip to below the lower lip: the mouth and what may be before it
};

class FaceAppearance {
 public:
  static constexpr int kColumns = 12, kRows = 10, kSamples = kColumns * kRows;

  explicit FaceAppearance(FaceRegion region = FaceRegion::kUpperFace) : region_(region) {}

  /// Takes the template from a frame whose face was just detected. False (and no template)
  /// when the grid leaves the image or the face has no texture.
  bool capture(const cv::Mat& gray, const Landmarks2D& landmarks);

  struct Match {
    double similarity = -1;  // normalised correlation in [-1, 1] with the template
    double luma = 0;         // mean luma of this frame's grid
    bool in_picture = false;  // the grid lies in the image
    bool textured = false;    // and has texture: `grid` is this frame's, normalised
    std::array<float, kSamples> grid{};
  };
  /// This frame's grid, sampled at `landmarks`, against the template; similarity -1 without
  /// a template, when the grid leaves the image or has no texture. Allocates nothing.
  Match compare(const cv::Mat& gray, const Landmarks2D& landmarks) const;

  /// Takes the grid a compare() sampled as the template, as capture() would from that frame
  /// (no template when it had no texture), without sampling it again.
  void take(const Match& match);

  bool captured() const { return captured_; }
  /// Mean luma of the template's grid.
  double luma() const { return luma_; }

 private:
  FaceRegion region_;
  std::array<float, kSamples> template_{};  // zero mean, unit norm
  double luma_ = 0;
  bool captured_ = false;
};

}  // namespace lipdrive
