// Lip contact from the pixels (DESIGN.md 4.8): whether the lips touch (`seal`) and the
// uncalibrated mouth opening `open` that drives the figure.
//
// Why pixels: the landmark regression starts every frame from a mean shape with a half-open
// mouth and lags toward it on short closures, so sealed lips can read 0.2 d open; the 3DMM fit
// (regularised towards the model's mean) loses more of them. Between sealed lips the image
// shows only the line where they meet; an open mouth shows a dark cavity and/or teeth.
//
// How: five vertical luma profiles across the central 60 % of the inner mouth, each from above
// the upper lip to below the lower lip along the face's own vertical (the eye line's normal),
// each sample the mean over its profile's share of the mouth width. Every luma is compared with
// the lips' own (the median of the lip bands between the outer and inner contours), so gain,
// skin tone and lighting cancel; positions are in units of d (DESIGN.md 4.4), so the measure
// does not depend on the image resolution. Two pieces of evidence that the lips are apart:
//  - darkness: where the lips meet, the integral along the profile of how much darker than the
//    lips each sample is (1 - luma / lip luma), less that of the line between sealed lips,
//    over d. Blur spreads the line and the cavity's edges but keeps the integral, and no
//    threshold decides what counts as dark;
//  - texture: how far the profile there departs from a single valley (down to the line, up
//    again): teeth between the lips add a bright band and a second dark line, even where they
//    are hardly brighter than the lips (grey, evenly lit faces).
// With a colour camera (a Cr plane beside the luma) a third, which replaces the texture:
//  - pallor: the same integral of how much less red than the lips each sample is
//    (1 - Cr' / lip Cr', Cr' = Cr - 128). Teeth and the mouth's inside are not lip-coloured,
//    however grey or evenly lit, while the lips' own shading (a blurred upper lip reads lip,
//    bright, dark like teeth in luma) keeps their colour.
// seal falls from 1 to 0 as the stronger evidence (the darkness, or the texture or pallor)
// passes its threshold, and only while the landmarks' own inner-lip height is one a lagging
// closure can show (<= 0.3 d). open is the landmark inner-lip height (the image, not the fit:
// the fit loses closures the landmarks had) times (1 - seal): sealed lips read 0, an open
// mouth keeps its landmark height.
//
// The thresholds were set on the first 25 clips (file-name order, bbal9a .. pbai5s) of the
// GRID development set and checked on the other 25 and two further clips
// (tests/test_lip_contact_eval.cpp reports both).
#pragma once

#include "core/landmarks.hpp"

#include <opencv2/core/mat.hpp>

namespace lipdrive {

struct LipContactSettings {
  /// Profiles across the inner mouth, evenly spread over the central `column_span` of the
  /// inner lip width (corners 60..64), and samples along each.
  static constexpr int kColumns = 5, kSamples = 48;
  double column_span = 0.6;
  /// How far each profile reaches beyond the outer lip contour, and how far beyond the inner
  /// contours the lips are taken to meet (the landmarks' error), both over d.
  double extend = 0.15;
  double margin = 0.05;
  /// The darkness of the line between sealed lips (its width x relative darkness, over d),
  /// taken off the darkness integral. The crease where the lips meet and their rounding into it
  /// are the face's own, so the line's integral grows with the face's size in the image (blur
  /// spreads it but keeps it): 1.2 px at GRID's d of 24.6 px.
  double line_darkness = 0.049;
  /// The pixels say "apart" at darkness >= open_darkness (over d) or texture >= open_texture
  /// (over the lips' luma); seal_softness is the width of the transition, in units of those
  /// thresholds.
  double open_darkness = 0.025;
  double open_texture = 0.05;
  /// With colour: the pallor of the line between sealed lips (pixels x relative pallor), taken
  /// off the pallor integral; the pixels say "apart" at pallor >= open_pallor (over d). Lips
  /// whose Cr' is under min_lip_red (grey lips, a camera's colour too weak) give no pallor.
  double line_pallor_px = 0.5;
  double open_pallor = 0.025;
  double min_lip_red = 4;
  double seal_softness = 0.25;
  /// Landmark inner-lip heights (H/d) above this are wider than any lagging closure: no seal.
  double max_sealed_height = 0.3;
  double height_softness = 0.02;
};

/// The pixel evidence of one frame.
struct LipGap {
  bool valid = false;   // the mouth is inside the image and its lips are not black
  double darkness = 0;  // median over the profiles of the darkness integral where the lips meet, over d
  double texture = 0;   // median excess variation there (teeth), over the lips' luma
  double lip_luma = 0;  // median luma of the lip bands
  bool colour = false;  // the pallor below was measured (a Cr plane, red enough lips)
  double pallor = 0;    // median over the profiles of the pallor integral where the lips meet, over d
  double lip_red = 0;   // median Cr - 128 of the lip bands
};

/// The gap between the lips in the luma image `gray` (CV_8UC1) of a face with `landmarks`, and
/// its red-difference chroma `cr` (CV_8UC1 at the luma's size or a whole fraction of it;
/// empty from a monochrome camera). Allocates nothing; about 1,000 bilinear taps per plane.
LipGap measure_lip_gap(const cv::Mat& gray, const cv::Mat& cr, const Landmarks2D& landmarks,
                       const LipContactSettings& settings = {});

/// Probability in [0, 1] that the lips touch, from the pixel evidence and the landmarks'
/// inner-lip height (H/d); 0 without pixel evidence.
double seal_probability(const LipGap& gap, double landmark_height, const LipContactSettings& settings = {});

/// The mouth opening in H/d units that drives the `open` signal: the landmark inner-lip
/// height, closed as far as the lips are sealed.
double fused_opening(double landmark_height, double seal);

}  // namespace lipdrive
