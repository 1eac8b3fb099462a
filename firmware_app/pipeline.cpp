#include "firmware_app/pipeline.hpp"

#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <algorithm>
#include <cmath>

namespace lipdrive {
namespace {

// A capture loop that has not come back from grab() for this long is stuck (grab() returns
// at least every grab_timeout), and the watchdog must stop being fed.
constexpr std::int64_t kCaptureStallNs = 1'000'000'000;

double ms(std::int64_t ns) { return static_cast<double>(ns) / 1e6; }

}  // namespace

Pipeline::Pipeline(std::unique_ptr<FrameSource> source, std::unique_ptr<FrameProcessor> processor,
                   PipelineSettings settings)
    : source_(std::move(source)),
      processor_(std::move(processor)),
      settings_(std::move(settings)),
      source_description_(source_->describe()),
      channels_(settings_.channels, settings_.safety) {
  const double fps = source_->frame_rate();
  const auto period_ns = static_cast<std::int64_t>(1e9 / (fps > 0 ? fps : 30.0));
  // Three frame periods: a late frame is not a loss, a camera that stopped delivering is.
  max_result_age_ns_ = 3 * period_ns;
  half_period_ns_ = period_ns / 2;
  profile_.publish(PerformerProfile{});
}

Pipeline::~Pipeline() { stop(); }

void Pipeline::start() {
  start_ns_ = monotonic_ns();
  capture_heartbeat_ns_ = start_ns_;
  last_watchdog_ns_ = 0;
  if (side_) side_->start();
  capture_thread_ = std::thread(&Pipeline::capture_loop, this);
  processing_thread_ = std::thread(&Pipeline::processing_loop, this);
  output_thread_ = std::thread(&Pipeline::output_loop, this);
}

void Pipeline::stop() {
  // Capture and processing first, so the neutral result is the last thing outputs see.
  if (stop_ns_ == 0 && start_ns_ > 0) stop_ns_ = monotonic_ns();
  stop_processing_ = true;
  if (capture_thread_.joinable()) capture_thread_.join();
  if (processing_thread_.joinable()) processing_thread_.join();
  if (side_) side_->stop();
  stop_outputs_ = true;
  if (output_thread_.joinable()) output_thread_.join();
}

void Pipeline::capture_loop() {
  Frame frame;
  while (!stop_processing_.load(std::memory_order_relaxed)) {
    GrabStatus status;
    try {
      status = source_->grab(frame, settings_.grab_timeout);
    } catch (const std::exception& e) {
      spdlog::error("{}: {}", source_description_, e.what());
      failed_ = true;
      break;
    }
    capture_heartbeat_ns_.store(monotonic_ns(), std::memory_order_relaxed);
    switch (status) {
      case GrabStatus::kFrame: {
        CapturedFrame& slot = frames_.back();
        frame.gray.copyTo(slot.gray);
        slot.capture_time_ns = frame.capture_time_ns;
        slot.sequence = frame.sequence;
        slot.media_time_s = frame.media_time_s;
        frames_.publish();
        captured_.fetch_add(1, std::memory_order_relaxed);
        if (!connected_.exchange(true)) spdlog::info("{}: delivering frames again", source_description_);
        break;
      }
      case GrabStatus::kDisconnected:
        // Logged once per outage; the source keeps trying to reopen by itself.
        if (connected_.exchange(false)) {
          disconnects_.fetch_add(1, std::memory_order_relaxed);
          spdlog::warn("{}: disconnected; the drive holds, then eases to neutral until it is back", source_description_);
        }
        break;
      case GrabStatus::kCorrupt:
        corrupt_.fetch_add(1, std::memory_order_relaxed);
        spdlog::debug("{}: a corrupt frame was skipped", source_description_);
        break;
      case GrabStatus::kEndOfStream:
        spdlog::info("{}: end of the recording", source_description_);
        source_ended_ = true;
        return;
      case GrabStatus::kTimeout:
        break;
    }
  }
}

void Pipeline::processing_loop() {
  const auto wait = std::chrono::nanoseconds(settings_.frame_wait);
  while (!stop_processing_.load(std::memory_order_relaxed)) {
    if (const CapturedFrame* frame = frames_.take(wait)) {
      process(*frame);
    } else if (source_ended_ || failed_) {
      finished_.store(true, std::memory_order_release);
    }
    ping_watchdog(monotonic_ns());
  }
}

void Pipeline::process(const CapturedFrame& frame) {
  const FrameMeasurement& measurement = processor_->process(frame.gray);
  FrameResult result;
  result.sequence = frame.sequence;
  result.capture_time_ns = frame.capture_time_ns;
  result.media_time_s = frame.media_time_s;
  result.tracked = measurement.tracked;
  if (measurement.tracked) {
    result.measures = measurement.measures;
    result.visemes = measurement.visemes;
    PerformerProfile profile;
    profile_.read(profile);
    result.signals = drive_signals(measurement.measures, measurement.visemes, profile);
    if (const auto side = side_ ? side_->protrusion_near(frame.capture_time_ns, half_period_ns_) : std::nullopt) {
      result.side_used = true;
      result.protrusion_side = *side;
      result.signals[Signal::kProtrusion] = static_cast<float>(profile.protrusion_side.scale(*side));
    }
  }
  result.width = frame.gray.cols;
  result.height = frame.gray.rows;
  result.processed_time_ns = monotonic_ns();
  processed_latency_.add(result.processed_time_ns - result.capture_time_ns);

  if (was_tracked_ && !result.tracked) lost_track_.fetch_add(1, std::memory_order_relaxed);
  was_tracked_ = result.tracked;
  tracked_.fetch_add(result.tracked, std::memory_order_relaxed);
  results_.publish(result);
  for (ResultSink* sink : sinks_) sink->push(result);
  const std::uint64_t processed = processed_.fetch_add(1, std::memory_order_relaxed) + 1;
  if (settings_.max_frames > 0 && processed >= settings_.max_frames) finished_.store(true, std::memory_order_release);
}

void Pipeline::ping_watchdog(std::int64_t now_ns) {
  if (settings_.watchdog_interval.count() == 0) return;
  if (now_ns - last_watchdog_ns_ < std::chrono::nanoseconds(settings_.watchdog_interval).count()) return;
  // A stuck capture thread stalls the pipeline just as surely as a stuck processing loop.
  if (now_ns - capture_heartbeat_ns_.load(std::memory_order_relaxed) > kCaptureStallNs) return;
  last_watchdog_ns_ = now_ns;
  sd_notify(0, "WATCHDOG=1");
}

void Pipeline::output_loop() {
  FrameResult result;
  DriveFrame frame;
  std::uint32_t seen = 0;
  const auto tick = std::chrono::nanoseconds(settings_.output_tick);
  std::uint64_t processed_before = 0;
  std::int64_t fps_since_ns = monotonic_ns();
  while (!stop_outputs_.load(std::memory_order_relaxed)) {
    results_.wait_newer(seen, tick);
    const std::uint32_t version = results_.read(result);
    frame.new_result = version != seen;
    seen = version;
    const std::int64_t now = monotonic_ns();
    if (frame.new_result && version > 0) output_latency_.add(now - result.capture_time_ns);

    for (int i = 0; i < channels_.size(); ++i)
      channels_.set_override(i, control_.overrides[static_cast<std::size_t>(i)].load(std::memory_order_relaxed));
    const bool enabled = control_.outputs_enabled.load(std::memory_order_relaxed);
    // A tracked result stops counting as tracking the moment the camera goes away or stops
    // delivering, not when the processing thread next publishes: the hold time starts there.
    const bool connected = connected_.load(std::memory_order_relaxed);
    const bool tracked = result.tracked && connected && now - result.capture_time_ns <= max_result_age_ns_;
    channels_.step(result.signals,
                   {.tracked = tracked, .enabled = enabled, .now_ns = now, .frame_time_ns = result.capture_time_ns});

    // Frames per second over the last second or so.
    if (now - fps_since_ns >= 1'000'000'000) {
      const std::uint64_t processed = processed_.load(std::memory_order_relaxed);
      frame.fps = static_cast<float>(static_cast<double>(processed - processed_before) * 1e9 /
                                     static_cast<double>(now - fps_since_ns));
      processed_before = processed;
      fps_since_ns = now;
    }
    std::uint16_t status = control_.daemon_status.load(std::memory_order_relaxed);
    if (tracked) status |= kStatusTracking;
    if (tracked && result.side_used) status |= kStatusSideCamera;
    if (channels_.fail_safe_active()) status |= kStatusFailSafe;
    if (enabled) status |= kStatusOutputsEnabled;
    if (connected) status |= kStatusCameraConnected;
    frame.status = status;
    frame.sequence = result.sequence;
    frame.capture_time_ns = result.capture_time_ns;
    frame.latency_ms = static_cast<float>(ms(result.processed_time_ns - result.capture_time_ns));
    fill(frame, now);
    for (Output* output : outputs_) output->publish(frame);
  }
  // The last thing every output sees: the neutral pose.
  channels_.reset_to_neutral();
  frame.new_result = false;
  frame.status = static_cast<std::uint16_t>((frame.status & ~kStatusTracking) | kStatusFailSafe);
  fill(frame, monotonic_ns());
  for (Output* output : outputs_) output->publish_last(frame);
}

void Pipeline::fill(DriveFrame& frame, std::int64_t now_ns) {
  ++frame.counter;
  frame.time_ns = now_ns;
  frame.channel_count = channels_.size();
  std::ranges::copy(channels_.values(), frame.values.begin());
  drive_frames_.publish(frame);
}

PipelineStats Pipeline::stats() const {
  PipelineStats s;
  s.captured = captured_.load(std::memory_order_relaxed);
  s.processed = processed_.load(std::memory_order_relaxed);
  s.tracked = tracked_.load(std::memory_order_relaxed);
  s.dropped = frames_.dropped();
  s.lost_track = lost_track_.load(std::memory_order_relaxed);
  s.disconnects = disconnects_.load(std::memory_order_relaxed);
  s.corrupt = corrupt_.load(std::memory_order_relaxed);
  s.processed_median_ms = processed_latency_.quantile_ms(0.5);
  s.processed_p99_ms = processed_latency_.quantile_ms(0.99);
  s.output_median_ms = output_latency_.quantile_ms(0.5);
  s.output_p99_ms = output_latency_.quantile_ms(0.99);
  const std::int64_t end_ns = stop_ns_ > 0 ? stop_ns_.load() : monotonic_ns();
  s.seconds = start_ns_ > 0 ? static_cast<double>(end_ns - start_ns_) / 1e9 : 0;
  s.connected = connected_.load(std::memory_order_relaxed);
  return s;
}

}  // namespace lipdrive
