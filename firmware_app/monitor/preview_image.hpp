// The monitor's preview images (docs/monitor.md): a PreviewFrame's front and side images drawn
// with their overlays and encoded as JPEG, on the monitor's encoder thread.
#pragma once

#include "drivers/image_codec.hpp"
#include "firmware_app/daemon/preview_feed.hpp"

#include <opencv2/core/mat.hpp>

#include <string>

namespace lipdrive {

/// The frame in grey with, when it was tracked, the face box (the landmarks' extent) in
/// yellow, the fitted model's lip contours (outer and inner) in magenta and the tracked
/// landmarks as green dots; "no face" in red when it was not. `canvas` is the caller's
/// scratch image, reused from one call to the next. JPEG bytes from `encoder`.
std::string preview_jpeg(const PreviewFrame& frame, cv::Mat& canvas, JpegEncoder& encoder);

/// The side camera's image of `frame` (frame.side must be set) in grey with the profile's
/// points as far as they were found: nose root and tip joined in yellow, subnasale in green,
/// upper lip in magenta with its lead over the nose tip as a horizontal line; what was not
/// found, or "side camera lost", in red. JPEG bytes from `encoder`.
std::string side_preview_jpeg(const PreviewFrame& frame, cv::Mat& canvas, JpegEncoder& encoder);

}  // namespace lipdrive
