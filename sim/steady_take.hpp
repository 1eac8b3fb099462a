// A still photograph as a take from a head-mounted camera: the camera moves with the head, so
// the face stays nearly where it is, swaying a little, while the light breathes and the sensor
// adds its noise. It lets the tracker's checks, made on one speaker's video, meet the faces of
// a set of photographs (beards, glasses, skin tones) frame after frame.
#pragma once

#include "core/landmarks.hpp"

#include <opencv2/core/mat.hpp>
#include <opencv2/core/matx.hpp>

#include <vector>

namespace lipdrive {

struct SteadyTake {
  std::vector<cv::Mat> frames;
  /// Frame f's pixel coordinates of a point of the photograph: where[f] * (x, y, 1).
  std::vector<cv::Matx23d> where;
};

/// `frames` frames of `photo` (grey or colour) around `face` (its landmarks in the photograph),
/// scaled so that the face's outer eye corners lie `interocular_px` apart, on a canvas three
/// times the landmarks' box across and down. Frame by frame the face turns by up to 3 degrees,
/// its size changes by up to 3 % and it moves by up to 3 % of the canvas, each slowly and out
/// of step with the others; the light rises and falls by 10 %; the noise is Gaussian, 2 levels,
/// the same for every call.
SteadyTake steady_take(const cv::Mat& photo, const Landmarks2D& face, int frames, double interocular_px = 90);

}  // namespace lipdrive
