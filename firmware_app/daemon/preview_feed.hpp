// The monitor page's view of the frame path (docs/monitor.md): a few times a second the
// processing thread copies the frame it just measured, scaled down, with its landmarks and the
// fitted model's projected landmarks, into a latest-frame-wins hand-off (latest_frame.hpp).
// The monitor's own thread takes it from there to draw and encode it; nothing of that work
// runs on the frame path.
//
// Thread model: offer() belongs to the processing thread, take() to one reader thread. offer()
// never waits, and allocates nothing once each of the three slots has held a frame of the
// current size.
#pragma once

#include "core/landmarks.hpp"
#include "firmware_app/daemon/latest_frame.hpp"

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
};

class PreviewFeed {
 public:
  /// At most `fps` previews a second (by capture time), each at most `max_side` pixels wide
  /// and high.
  PreviewFeed(double fps, int max_side);

  /// Processing thread, once per measured frame: copies it when a preview is due, else returns
  /// at once. `landmarks` and `fitted` are read only when `tracked`.
  void offer(const cv::Mat& gray, std::uint64_t sequence, std::int64_t capture_time_ns, bool tracked,
             const Landmarks2D& landmarks, const Landmarks2D& fitted);

  /// The reader: the newest preview, or nullptr when none arrives within `timeout`; it stays the
  /// reader's until the next take().
  const PreviewFrame* take(std::chrono::nanoseconds timeout) { return frames_.take(timeout); }

  /// Previews copied so far (processing thread's count; any thread may read it).
  std::uint64_t offered() const { return offered_.load(std::memory_order_relaxed); }

 private:
  const std::int64_t period_ns_;
  const int max_side_;
  std::int64_t next_ns_ = 0;  // processing thread's: capture time the next preview is due at
  LatestFrame<PreviewFrame> frames_;
  std::atomic<std::uint64_t> offered_{0};
};

}  // namespace lipdrive
