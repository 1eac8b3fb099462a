// A still photograph as a take from a head-mounted camera: the camera moves with the head, so
// the face stays nearly where it is, swaying a little, while the light breathes and the sensor
// adds its noise. It lets the tracker's checks, made on one speaker's video, meet the faces of
// a set of photographs (beards, glasses, skin tones) frame after frame.
#pragma once

#include "core/landmarks.hpp"

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <vector>

namespace lipdrive {

struct SteadyTake {
  std::vector<cv::Mat> frames;
  /// Where frame f shows a point p of the photograph: where[f] * (p, 1).
  std::vector<Eigen::Matrix<double, 2, 3>> where;

  /// Landmarks of the photograph, as frame f shows them.
  Landmarks2D in_frame(std::size_t f, const Landmarks2D& p) const {
    return where[f].leftCols<2>() * p + where[f].col(2).replicate(1, kNumLandmarks);
  }
};

/// `frames` frames of `photo` (grey or colour) around `face` (its landmarks in the photograph),
/// scaled so that the face's outer eye corners lie `interocular_px` apart, on a canvas three
/// times the landmarks' box across and down. Frame by frame the face turns by up to 3 degrees,
/// its size changes by up to 3 % and it moves by up to 3 % of the canvas, each slowly and out
/// of step with the others; the light rises and falls by 10 %; the noise is Gaussian, 2 levels,
/// the same for every call.
SteadyTake steady_take(const cv::Mat& photo, const Landmarks2D& face, int frames, double interocular_px = 90);

}  // namespace lipdrive
