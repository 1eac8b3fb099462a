// The monitor page's view of the frame path (docs/monitor.md): a few times a second the
// processing thread copies the frame it just measured, scaled down, with its landmarks and the
// fitted model's projected landmarks, and the side camera's newest frame with its profile
// when there is one, into a latest-frame-wins hand-off (latest_frame.hpp).
// The monitor's own thread takes it from there to draw and encode it; nothing of that work
// runs on the frame path.
//
// Thread model: offer() belongs to the processing thread, take() to one reader thread. offer()
// never waits, and allocates nothing once each of the three slots has held a frame of the
// current size.
#pragma once

#include "core/landmarks.hpp"
#include "core/side_profile.hpp"
#include "firmware_app/daemon/latest_frame.hpp"
#include "firmware_app/daemon/side_camera.hpp"

#include <opencv2/core/mat.hpp>

#include <chrono>
#include <cstdint>

namespace lipdrive {

/// One preview in the hand-off.
struct PreviewFrame {
  cv::Mat image;       // the luma plane, every `decimation`-th pixel of every `decimation`-th row
  int decimation = 1;  // frame pixel = image pixel * decimation
  bool tracked = false;
  Landmarks2D landmarks;  // the tracked landmarks (frame pixels), valid when tracked
  Landmarks2D fitted;     // the fitted model's 68 landmarks projected (frame pixels; NaN if unmapped)
  std::uint64_t sequence = 0;
  std::int64_t capture_time_ns = 0;

  // The side camera's newest frame, when one is configured and has delivered a frame.
  bool side = false;
  cv::Mat side_image;  // decimated as `image`, by side_decimation
  int side_decimation = 1;
  SideProfile side_profile;  // frame pixels of the side camera
  bool side_connected = false;
};

class PreviewFeed {
 public:
  /// At most `fps` previews a second (by capture time), each at most `max_side` pixels wide
  /// and high.
  PreviewFeed(double fps, int max_side);

  /// Whether a frame captured at `capture_time_ns` would be copied (processing thread).
  bool due(std::int64_t capture_time_ns) const { return capture_time_ns >= next_ns_; }

  /// Processing thread, once per measured frame: copies it when a preview is due, else returns
  /// at once. `landmarks` and `fitted` are read only when `tracked`; `side.gray` when not null.
  void offer(const cv::Mat& gray, std::uint64_t sequence, std::int64_t capture_time_ns, bool tracked,
             const Landmarks2D& landmarks, const Landmarks2D& fitted, const SideView& side = {});

  /// The reader: the newest preview, or nullptr when none arrives within `timeout`; it stays the
  /// reader's until the next take().
  const PreviewFrame* take(std::chrono::nanoseconds timeout) { return frames_.take(timeout); }

  /// Previews copied so far (processing thread's count; any thread may read it).
  std::uint64_t offered() const { return offered_.load(std::memory_order_relaxed); }

 private:
  /// The k that fits every k-th pixel of `frame` into max_side_.
  int decimation(const cv::Mat& frame) const;

  const std::int64_t period_ns_;
  const int max_side_;
  std::int64_t next_ns_ = 0;  // processing thread's: capture time the next preview is due at
  LatestFrame<PreviewFrame> frames_;
  std::atomic<std::uint64_t> offered_{0};
};

}  // namespace lipdrive
