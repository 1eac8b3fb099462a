// Frames in which the tracked face stops being where the tracker last saw it, made from a
// clean clip (DESIGN.md 6): a cut to another shot with the face elsewhere, the face leaving
// the frame, a hand over the lens, a card or a hand before the mouth. The face's true
// landmarks follow from the clean clip's (shifted by the same offset), so a test can tell a
// frame tracked on the face from one tracked on whatever replaced it.
#pragma once

#include "core/landmarks.hpp"

#include <opencv2/core/mat.hpp>

#include <cstdint>

namespace lipdrive {

/// `gray` moved by (dx, dy) pixels; what comes in from outside the frame is `fill` (a wall
/// behind the performer), or the nearest edge pixel when `fill` is negative.
cv::Mat shifted_frame(const cv::Mat& gray, double dx, double dy, int fill = -1);

/// `gray` with its bottom `fraction` (0..1) hidden behind something dark and out of focus
/// rising in front of the lens: blurred noise around `luma`, the same for a given `seed`.
cv::Mat covered_frame(const cv::Mat& gray, double fraction, double luma = 30, std::uint64_t seed = 1);

/// `image` (grey or colour) with `thing` (a card, a hand: any picture of the same type) held in
/// front of `area`, scaled to cover it.
cv::Mat held_before(const cv::Mat& image, const cv::Rect& area, const cv::Mat& thing);

/// Where a thing held before the mouth of `face` covers: the box of its 20 mouth landmarks
/// grown by 0.3 inter-ocular distances on every side.
cv::Rect before_the_mouth(const Landmarks2D& face);

/// A hand, for held_before: the face's own forehead above its brows (between the brows'
/// middles, from 0.15 to 0.55 inter-ocular distances above them, as far as the picture holds
/// it) in `image` (grey or colour): skin of the performer's own tone, texture and light.
cv::Mat hand_of(const cv::Mat& image, const Landmarks2D& face);

}  // namespace lipdrive
