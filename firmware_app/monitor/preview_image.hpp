// The monitor's preview image (docs/monitor.md): a PreviewFrame drawn with its overlay and
// encoded as JPEG, on the monitor's encoder thread.
#pragma once

#include "firmware_app/daemon/preview_feed.hpp"

#include <opencv2/core/mat.hpp>

#include <string>

namespace lipdrive {

/// The frame in grey with, when it was tracked, the face box (the landmarks' extent) in
/// yellow, the fitted model's lip contours (outer and inner) in magenta and the tracked
/// landmarks as green dots; "no face" in red when it was not. `canvas` is the caller's
/// scratch image, reused from one call to the next. JPEG bytes at `quality` (1..100).
std::string preview_jpeg(const PreviewFrame& frame, cv::Mat& canvas, int quality);

}  // namespace lipdrive
