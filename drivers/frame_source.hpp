// The one interface every camera implements: V4L2, libcamera and the simulated camera.
//
// Thread model: a FrameSource is owned and called by exactly one thread (the capture
// thread of the pipeline, or the caller of `lipdrive process`).
#pragma once

#include <opencv2/core/mat.hpp>

#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace lipdrive {

struct Frame {
  cv::Mat gray;                      // 8-bit luma plane (CV_8UC1); may point into the source's
                                     // buffers: valid until the next grab() on the same source
  cv::Mat cr;                        // 8-bit red-difference chroma (Cr, 128 = no colour) at the
                                     // luma's size or a whole fraction of it (4:2:0, 4:2:2);
                                     // empty from a monochrome camera; valid as long as `gray`
  std::int64_t capture_time_ns = 0;  // CLOCK_MONOTONIC at capture
  std::uint64_t sequence = 0;        // counts delivered frames from 0; gaps = frames lost
  double media_time_s = 0;           // position in the recording (replay) or since start (live)
  std::string_view source;           // file name of an image, path of a video, or device name
};

/// A source that cannot be opened at all (missing path, no images, not a video); the
/// message names the path and the reason.
class SourceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class GrabStatus {
  kFrame,         // `frame` holds a new frame
  kTimeout,       // nothing arrived within the timeout; try again
  kEndOfStream,   // a recording ended (never for live cameras or looping replay)
  kDisconnected,  // the device went away; grab() keeps trying to reopen it
  kCorrupt,       // a frame arrived but could not be decoded; the next one may be fine
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual GrabStatus grab(Frame& frame, std::chrono::milliseconds timeout) = 0;
  /// Nominal frame rate (frames per second), 0 if unknown.
  virtual double frame_rate() const = 0;
  /// Human-readable name for logs and status ("sim:clip.mp4", "/dev/video0").
  virtual std::string describe() const = 0;
};

}  // namespace lipdrive
