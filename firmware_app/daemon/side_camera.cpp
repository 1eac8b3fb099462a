#include "firmware_app/daemon/side_camera.hpp"

#include "drivers/clock.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdlib>
#include <utility>

namespace lipdrive {

SideCamera::SideCamera(std::unique_ptr<FrameSource> source, SideProfileSettings settings, int neutral_frames)
    : capture_(std::move(source), "side camera", "protrusion comes from the front camera's fit"),
      meter_(settings),
      neutral_(static_cast<std::size_t>(std::max(neutral_frames, 1))) {}

const CapturedFrame* SideCamera::nearest(std::int64_t front_time_ns, std::int64_t half_period_ns) {
  if (const CapturedFrame* newer = capture_.take(std::chrono::nanoseconds(0))) current_ = newer;
  // The side frame at hand is older than the pairing window: the matching one may still be on
  // its way. Wait for it, but never past the window's end.
  while (connected() && (!current_ || current_->capture_time_ns < front_time_ns - half_period_ns)) {
    const std::int64_t wait_ns = front_time_ns + half_period_ns - monotonic_ns();
    if (wait_ns <= 0) break;
    const CapturedFrame* newer = capture_.take(std::chrono::nanoseconds(wait_ns));
    if (!newer) break;
    current_ = newer;
  }
  if (!current_ || std::llabs(current_->capture_time_ns - front_time_ns) > half_period_ns) return nullptr;
  return current_;
}

std::optional<double> SideCamera::protrusion_near(std::int64_t front_time_ns, std::int64_t half_period_ns) {
  const CapturedFrame* frame = nearest(front_time_ns, half_period_ns);
  if (!frame) return std::nullopt;
  if (!reference_) {
    frame->gray.copyTo(neutral_[static_cast<std::size_t>(neutral_count_++)]);
    if (neutral_count_ < static_cast<int>(neutral_.size())) return std::nullopt;
    neutral_count_ = 0;
    try {
      reference_ = calibrate_side(meter_, neutral_);
      spdlog::info("{}: reference fixed (nose {:.1f} px)", capture_.name(), reference_->nose_length_px);
      failing_ = false;
    } catch (const SideCalibrationError& e) {
      if (!std::exchange(failing_, true))
        spdlog::warn("{}: {}; trying again on the next frames", capture_.name(), e.what());
    }
    return std::nullopt;
  }
  const SideMeasure measure = meter_.measure(frame->gray, *reference_);
  profile_ = measure.profile;
  profiled_ = frame;
  profiled_sequence_ = frame->sequence;
  if (!measure.ok()) return std::nullopt;
  return measure.protrusion;
}

SideView SideCamera::view() {
  if (const CapturedFrame* newer = capture_.take(std::chrono::nanoseconds(0))) current_ = newer;
  if (!current_) return {};
  if (profiled_ != current_ || profiled_sequence_ != current_->sequence) {
    profile_ = meter_.find(current_->gray);
    profiled_ = current_;
    profiled_sequence_ = current_->sequence;
  }
  return {.gray = &current_->gray, .profile = profile_, .connected = connected()};
}

}  // namespace lipdrive
