#include "firmware_app/side_camera.hpp"

#include "firmware_app/latency_histogram.hpp"

#include <spdlog/spdlog.h>

#include <cstdlib>

namespace lipdrive {

SideCamera::SideCamera(std::unique_ptr<FrameSource> source, SideProfileSettings settings, int neutral_frames)
    : source_(std::move(source)),
      description_(source_->describe()),
      meter_(settings),
      neutral_frames_(neutral_frames) {}

SideCamera::~SideCamera() { stop(); }

void SideCamera::start() { thread_ = std::thread(&SideCamera::capture_loop, this); }

void SideCamera::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void SideCamera::capture_loop() {
  Frame frame;
  while (!stop_.load(std::memory_order_relaxed)) {
    GrabStatus status;
    try {
      status = source_->grab(frame, std::chrono::milliseconds(100));
    } catch (const std::exception& e) {
      spdlog::error("side camera {}: {}; protrusion comes from the front camera's fit", description_, e.what());
      break;
    }
    if (status == GrabStatus::kFrame) {
      SideFrame& slot = frames_.back();
      frame.gray.copyTo(slot.gray);
      slot.capture_time_ns = frame.capture_time_ns;
      frames_.publish();
      if (!connected_.exchange(true)) spdlog::info("side camera {}: delivering frames", description_);
    } else if (status == GrabStatus::kDisconnected && connected_.exchange(false)) {
      spdlog::warn("side camera {}: disconnected; protrusion comes from the front camera's fit", description_);
    } else if (status == GrabStatus::kEndOfStream) {
      spdlog::info("side camera {}: end of the recording", description_);
      break;
    }
  }
  connected_ = false;
}

const SideCamera::SideFrame* SideCamera::nearest(std::int64_t front_time_ns, std::int64_t half_period_ns) {
  if (const SideFrame* newer = frames_.take(std::chrono::nanoseconds(0))) current_ = newer;
  // The side frame at hand is older than the pairing window: the matching one may still be on
  // its way. Wait for it, but never past the window's end.
  while (connected() && (!current_ || current_->capture_time_ns < front_time_ns - half_period_ns)) {
    const std::int64_t wait_ns = front_time_ns + half_period_ns - monotonic_ns();
    if (wait_ns <= 0) break;
    const SideFrame* newer = frames_.take(std::chrono::nanoseconds(wait_ns));
    if (!newer) break;
    current_ = newer;
  }
  if (!current_ || std::llabs(current_->capture_time_ns - front_time_ns) > half_period_ns) return nullptr;
  return current_;
}

std::optional<double> SideCamera::protrusion_near(std::int64_t front_time_ns, std::int64_t half_period_ns) {
  const SideFrame* frame = nearest(front_time_ns, half_period_ns);
  if (!frame) return std::nullopt;
  if (recalibrate_.exchange(false, std::memory_order_relaxed)) {
    reference_.reset();
    neutral_.clear();
  }
  if (!reference_) {
    // Fixing the reference allocates (a few frame copies), once per calibration, not per frame.
    neutral_.push_back(frame->gray.clone());
    if (static_cast<int>(neutral_.size()) < neutral_frames_) return std::nullopt;
    try {
      reference_ = calibrate_side(meter_, neutral_);
      spdlog::info("side camera {}: reference fixed (nose {:.1f} px)", description_, reference_->nose_length_px);
    } catch (const SideCalibrationError& e) {
      spdlog::warn("side camera {}: {}; trying again on the next frames", description_, e.what());
    }
    neutral_.clear();
    return std::nullopt;
  }
  const SideMeasure measure = meter_.measure(frame->gray, *reference_);
  if (!measure.ok()) return std::nullopt;
  return measure.protrusion;
}

}  // namespace lipdrive
