#include "firmware_app/daemon/preview_feed.hpp"

#include <algorithm>
#include <cstring>

namespace lipdrive {
namespace {

/// Every k-th pixel of every k-th row of `source` into `target` (nearest-neighbour
/// decimation): a fixed amount of work per preview and no scratch buffer, unlike cv::resize.
void decimate(const cv::Mat& source, int k, cv::Mat& target) {
  target.create(source.rows / k, source.cols / k, CV_8UC1);  // keeps the buffer while the size holds
  if (k == 1) {
    for (int y = 0; y < source.rows; ++y)
      std::memcpy(target.ptr(y), source.ptr(y), static_cast<std::size_t>(source.cols));
    return;
  }
  for (int y = 0; y < target.rows; ++y) {
    const std::uint8_t* in = source.ptr<std::uint8_t>(y * k);
    std::uint8_t* out = target.ptr<std::uint8_t>(y);
    for (int x = 0; x < target.cols; ++x) out[x] = in[x * k];
  }
}

}  // namespace

PreviewFeed::PreviewFeed(double fps, int max_side)
    : period_ns_(static_cast<std::int64_t>(1e9 / fps)), max_side_(max_side) {}

int PreviewFeed::decimation(const cv::Mat& frame) const {
  return std::max((std::max(frame.cols, frame.rows) + max_side_ - 1) / max_side_, 1);
}

void PreviewFeed::offer(const cv::Mat& gray, std::uint64_t sequence, std::int64_t capture_time_ns, bool tracked,
                        const Landmarks2D& landmarks, const Landmarks2D& fitted, const SideView& side) {
  if (!due(capture_time_ns) || gray.empty()) return;
  // A period after the last one was due, keeping the rate; a period from now after a pause.
  next_ns_ += period_ns_;
  if (next_ns_ <= capture_time_ns) next_ns_ = capture_time_ns + period_ns_;
  PreviewFrame& slot = frames_.back();
  slot.decimation = decimation(gray);
  decimate(gray, slot.decimation, slot.image);
  slot.side = side.gray != nullptr && !side.gray->empty();
  if (slot.side) {
    slot.side_decimation = decimation(*side.gray);
    decimate(*side.gray, slot.side_decimation, slot.side_image);
    slot.side_profile = side.profile;
    slot.side_connected = side.connected;
  }
  slot.tracked = tracked;
  if (tracked) {
    slot.landmarks = landmarks;
    slot.fitted = fitted;
  }
  slot.sequence = sequence;
  slot.capture_time_ns = capture_time_ns;
  frames_.publish();
  offered_.fetch_add(1, std::memory_order_relaxed);
}

}  // namespace lipdrive
