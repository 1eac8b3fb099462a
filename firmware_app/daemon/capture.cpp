#include "firmware_app/daemon/capture.hpp"

#include "drivers/clock.hpp"
#include "drivers/thread_scheduling.hpp"

#include <spdlog/spdlog.h>

namespace lipdrive {

Capture::Capture(std::unique_ptr<FrameSource> source, std::string_view role, std::string when_lost)
    : source_(std::move(source)),
      description_(source_->describe()),
      name_(role.empty() ? description_ : std::string(role) + " " + description_),
      when_lost_(std::move(when_lost)),
      frame_rate_(source_->frame_rate()) {}

Capture::~Capture() { stop(); }

std::string Capture::start(const char* thread_name, int realtime_priority) {
  heartbeat_ns_ = monotonic_ns();
  thread_ = std::thread(&Capture::run, this);
  return schedule_thread(thread_, thread_name, realtime_priority);
}

void Capture::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

CaptureCounters Capture::counters() const {
  return {captured_.load(std::memory_order_relaxed), frames_.dropped(), disconnects_.load(std::memory_order_relaxed),
          corrupt_.load(std::memory_order_relaxed)};
}

void Capture::run() {
  Frame frame;
  std::int64_t last_frame_ns = monotonic_ns();
  while (!stop_.load(std::memory_order_relaxed)) {
    GrabStatus status;
    try {
      status = source_->grab(frame, kGrabTimeout);
    } catch (const std::exception& e) {
      spdlog::error("{}: {}; {}", name_, e.what(), when_lost_);
      failed_.store(true, std::memory_order_release);
      return;
    }
    const std::int64_t now = monotonic_ns();
    heartbeat_ns_.store(now, std::memory_order_relaxed);
    switch (status) {
      case GrabStatus::kFrame: {
        CapturedFrame& slot = frames_.back();
        frame.gray.copyTo(slot.gray);
        frame.cr.copyTo(slot.cr);
        slot.capture_time_ns = frame.capture_time_ns;
        slot.sequence = frame.sequence;
        slot.media_time_s = frame.media_time_s;
        frames_.publish();
        last_frame_ns = now;
        const bool was_connected = connected_.exchange(true);
        const bool was_silent = silent_.exchange(false);
        const bool first = captured_.fetch_add(1, std::memory_order_relaxed) == 0;
        if (first || !was_connected) frame_rate_.store(source_->frame_rate(), std::memory_order_relaxed);
        if (first)
          spdlog::info("{}: delivering frames", name_);
        else if (!was_connected || was_silent)
          spdlog::info("{}: delivering frames again", name_);
        break;
      }
      case GrabStatus::kDisconnected:
        // Logged once per outage; the source keeps trying to reopen by itself. A camera away
        // before its first frame (not there at start) was never connected: not a disconnect.
        if (connected_.exchange(false) && captured_.load(std::memory_order_relaxed) > 0) {
          disconnects_.fetch_add(1, std::memory_order_relaxed);
          spdlog::warn("{}: disconnected; {}", name_, when_lost_);
        }
        break;
      case GrabStatus::kCorrupt:
        corrupt_.fetch_add(1, std::memory_order_relaxed);
        spdlog::debug("{}: a corrupt frame was skipped", name_);
        break;
      case GrabStatus::kEndOfStream:
        spdlog::info("{}: end of the recording", name_);
        ended_.store(true, std::memory_order_release);
        return;
      case GrabStatus::kTimeout:
        // Logged once per silence; a disconnect the source reports later is counted as before.
        if (now - last_frame_ns >= std::chrono::nanoseconds(kSilentAfter).count() && !silent_.exchange(true))
          spdlog::warn("{}: no frame for {} ms; {}", name_, (now - last_frame_ns) / 1'000'000, when_lost_);
        break;
    }
  }
}

}  // namespace lipdrive
