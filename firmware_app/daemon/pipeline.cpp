#include "firmware_app/daemon/pipeline.hpp"

#include "drivers/clock.hpp"
#include "drivers/thread_scheduling.hpp"

#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <algorithm>
#include <cmath>

namespace lipdrive {
namespace {

// A capture loop that has not come back from grab() for this long is stuck (grab() returns
// at least every Capture::kGrabTimeout), and so is an output loop that has not come round (it
// wakes at least every output tick; an output's publish() that blocks holds every output at its
// last values): the watchdog must stop being fed.
constexpr std::int64_t kThreadStallNs = 1'000'000'000;

double ms(std::int64_t ns) { return static_cast<double>(ns) / 1e6; }

// A stage the frame processor did not reach this frame reads NaN and is not counted.
void add_stage_time(LatencyHistogram& histogram, double ms) {
  if (!std::isnan(ms)) histogram.add(std::llround(ms * 1e6));
}

}  // namespace

Pipeline::Pipeline(std::unique_ptr<FrameSource> source, std::unique_ptr<FrameProcessor> processor,
                   PipelineSettings settings, DriveControl& control)
    : capture_(std::move(source), "", "the drive holds, then eases to neutral"),
      processor_(std::move(processor)),
      settings_(std::move(settings)),
      control_(control),
      channels_(settings_.channels, settings_.safety),
      hand_over_(std::chrono::nanoseconds(settings_.voice_crossfade).count()) {}

Pipeline::~Pipeline() { stop(); }

void Pipeline::set_profile(const PerformerProfile& profile) {
  profile_ = profile;
  output_profile_ = profile;
  calibrated_ = profile.calibrated;
}

void Pipeline::start() {
  start_ns_ = monotonic_ns();
  last_watchdog_ns_ = 0;
  output_heartbeat_ns_ = start_ns_;
  const int priority = settings_.realtime_priority;
  std::string refused;  // the first refusal: the reason is the same for every thread
  const auto note = [&refused](std::string why) {
    if (refused.empty()) refused = std::move(why);
  };
  if (side_) note(side_->start(priority));
  note(capture_.start("lipdrive-capture", priority));
  processing_thread_ = std::thread(&Pipeline::processing_loop, this);
  note(schedule_thread(processing_thread_, "lipdrive-process", priority));
  output_thread_ = std::thread(&Pipeline::output_loop, this);
  note(schedule_thread(output_thread_, "lipdrive-output", priority));
  if (!refused.empty())
    spdlog::warn("{}; the frame path runs under the normal scheduler (the service needs LimitRTPRIO={} and "
                 "RestrictRealtime=no)",
                 refused, priority);
  else if (priority > 0)
    spdlog::info("the frame path runs under SCHED_FIFO at priority {}", priority);
  if (settings_.cpu_latency_us >= 0) {
    if (const std::string why = cpu_latency_.request(settings_.cpu_latency_us); !why.empty())
      spdlog::warn("{}; the CPUs keep the system's idle states (the service needs write access to {}, "
                   "docs/packaging.md)",
                   why, CpuLatencyRequest::kDevice);
    else
      spdlog::info("the CPUs wake from idle within {} us while the frame path runs", settings_.cpu_latency_us);
  }
}

void Pipeline::stop(Leave leave) {
  // Capture and processing first, so the neutral pose is the last thing outputs see.
  if (stop_ns_ == 0 && start_ns_ > 0) stop_ns_ = monotonic_ns();
  stop_processing_ = true;
  capture_.stop();
  if (processing_thread_.joinable()) processing_thread_.join();
  frame_errors_.log_held_back("frames whose measuring threw");
  if (side_) side_->stop();
  leave_where_it_is_.store(leave == Leave::kWhereItIs, std::memory_order_relaxed);
  stop_outputs_ = true;
  if (output_thread_.joinable()) output_thread_.join();
  cpu_latency_.release();
}

// ---------------------------------------------------------------- processing thread

void Pipeline::processing_loop() {
  const auto wait = std::chrono::nanoseconds(settings_.frame_wait);
  while (!stop_processing_.load(std::memory_order_relaxed)) {
    const CapturedFrame* frame = nullptr;
    if (warm_at_ns_ > 0) {
      // Idle until shortly before the next frame is due, then read what it will need: in the
      // 16 ms between a camera's frames other work evicts the predictor's data from the cache.
      // (When the last frame ended later than that, what it read is still there.)
      const std::int64_t idle_ns = warm_at_ns_ - monotonic_ns();
      warm_at_ns_ = 0;
      if (idle_ns > 0) {
        frame = capture_.take(std::chrono::nanoseconds(idle_ns));
        if (frame == nullptr && processor_->warm()) warmed_.fetch_add(1, std::memory_order_relaxed);
      }
    }
    if (frame == nullptr) frame = capture_.take(wait);
    if (frame != nullptr) {
      try {
        process(*frame);
      } catch (const std::exception& e) {
        untrust(*frame, e.what());
      }
      warm_at_ns_ = warm_time(frame->capture_time_ns);
    } else if (capture_.ended() || capture_.failed()) {
      finished_.store(true, std::memory_order_release);
    }
    ping_watchdog(monotonic_ns());
  }
}

std::int64_t Pipeline::frame_period_ns() const {
  const double fps = capture_.frame_rate();
  return static_cast<std::int64_t>(1e9 / (fps > 0 ? fps : 30.0));
}

std::int64_t Pipeline::warm_time(std::int64_t capture_ns) {
  const std::int64_t interval_ns = capture_ns - last_capture_ns_;
  last_capture_ns_ = capture_ns;
  if (settings_.warm_ahead.count() <= 0) return 0;
  // The next frame is expected one interval after this one: the last interval, so that a camera
  // that slows down in the dark is followed; the nominal period after a gap or at the start.
  const std::int64_t period_ns = frame_period_ns();
  const bool recent = interval_ns > 0 && interval_ns < 4 * period_ns;
  return capture_ns + (recent ? interval_ns : period_ns) - std::chrono::nanoseconds(settings_.warm_ahead).count();
}

void Pipeline::process(const CapturedFrame& frame) {
  published_ = false;
  hand_off_time_.add(monotonic_ns() - frame.capture_time_ns);
  const FrameMeasurement& measurement = processor_->process(frame.gray, frame.cr);
  add_stage_time(landmarks_time_, measurement.landmarks_ms);
  add_stage_time(fit_time_, measurement.fit_ms);
  add_stage_time(measures_time_, measurement.measures_ms);
  FrameResult result;
  result.sequence = frame.sequence;
  result.capture_time_ns = frame.capture_time_ns;
  result.media_time_s = frame.media_time_s;
  if (timecode_) result.timecode = timecode_->frame_at(frame.capture_time_ns).value_or(-1);
  result.tracked = measurement.tracked;
  if (measurement.tracked) {
    result.measures = measurement.measures;
    result.visemes = measurement.visemes;
    result.signals = drive_signals(measurement.measures, measurement.visemes, profile_);
    if (const auto side = side_ ? side_->protrusion_near(frame.capture_time_ns, frame_period_ns() / 2) : std::nullopt) {
      result.side_used = true;
      result.protrusion_side = *side;
      result.signals[Signal::kProtrusion] = static_cast<float>(profile_.protrusion_side.scale(*side));
    }
    processor_->set_arkit(result.signals);
  }
  result.width = frame.gray.cols;
  result.height = frame.gray.rows;
  result.processed_time_ns = monotonic_ns();
  processed_latency_.add(result.processed_time_ns - result.capture_time_ns);
  publish(result);
  for (ResultSink* sink : sinks_) sink->push(result);
  if (preview_ && preview_->due(frame.capture_time_ns))
    preview_->offer(frame.gray, frame.sequence, frame.capture_time_ns, result.tracked, measurement.landmarks,
                    processor_->fit().projected, side_ ? side_->view() : SideView{});
  calibrate_step(result);
}

void Pipeline::publish(FrameResult& result) {
  VoiceState voice;
  bool heard = false;
  voice_state(result.processed_time_ns, voice, heard);
  result.drive = select_source(result.tracked, heard);
  if (was_tracked_ && !result.tracked) lost_track_.fetch_add(1, std::memory_order_relaxed);
  was_tracked_ = result.tracked;
  tracked_.fetch_add(result.tracked, std::memory_order_relaxed);
  results_.publish(result);
  published_ = true;
  const std::uint64_t processed = processed_.fetch_add(1, std::memory_order_relaxed) + 1;
  if (settings_.max_frames > 0 && processed >= settings_.max_frames) finished_.store(true, std::memory_order_release);
}

void Pipeline::untrust(const CapturedFrame& frame, const char* what) {
  std::uint64_t held_back = 0;
  const bool log = frame_errors_.pass(held_back);
  if (published_) {  // a consumer of the result failed (a sink, the preview): the drive has it
    if (log) spdlog::error("frame {}: {}{}", frame.sequence, what, held_back_note(held_back));
    return;
  }
  if (log)
    spdlog::error("frame {}: {}; the frame counts as untracked and the face is detected afresh{}", frame.sequence, what,
                  held_back_note(held_back));
  processor_->forget(FaceTracker::Next::kVideo);
  FrameResult result;
  result.sequence = frame.sequence;
  result.capture_time_ns = frame.capture_time_ns;
  result.media_time_s = frame.media_time_s;
  result.width = frame.gray.cols;
  result.height = frame.gray.rows;
  result.processed_time_ns = monotonic_ns();
  publish(result);
}

void Pipeline::calibrate_step(const FrameResult& result) {
  const std::uint32_t requests = control_.calibrate_requests.load(std::memory_order_relaxed);
  if (requests != calibrate_requests_seen_) {
    calibrate_requests_seen_ = requests;
    // A request while a capture is under way joins it.
    if (!capturing_neutral_) {
      capturing_neutral_ = true;
      neutral_.clear();
      if (side_) side_->recalibrate();
      spdlog::info("calibrating: hold a neutral face for {} tracked frames", settings_.neutral_frames);
    }
  }
  if (!capturing_neutral_ || !result.tracked) return;
  neutral_.add(result.measures);
  if (neutral_.size() < settings_.neutral_frames) return;
  capturing_neutral_ = false;
  // Once per calibration, not per frame: the medians allocate, the log lines too.
  try {
    profile_ = recentre(profile_, neutral_.samples());
    calibrated_ = true;
    recentred_.publish(profile_);
    spdlog::info("calibrated neutral: open {:.3f}, width {:.3f}, protrusion {:.3f}", profile_.rest.open,
                 profile_.rest.width, profile_.rest.protrusion);
  } catch (const CalibrationError& e) {
    spdlog::error("calibration failed: {}", e.what());
  }
}

void Pipeline::ping_watchdog(std::int64_t now_ns) {
  if (settings_.watchdog_interval.count() == 0) return;
  if (now_ns - last_watchdog_ns_ < std::chrono::nanoseconds(settings_.watchdog_interval).count()) return;
  // A stuck capture or output thread stalls the drive just as surely as a stuck processing loop.
  if (now_ns - capture_.heartbeat_ns() > kThreadStallNs) return;
  if (now_ns - output_heartbeat_ns_.load(std::memory_order_relaxed) > kThreadStallNs) return;
  last_watchdog_ns_ = now_ns;
  sd_notify(0, "WATCHDOG=1");
}

// ---------------------------------------------------------------- output thread

std::uint16_t Pipeline::status(bool tracked, bool side_used, bool connected, bool enabled, DriveSource source) const {
  return status_word({.tracking = tracked,
                      .calibrated = calibrated_.load(std::memory_order_relaxed),
                      .fail_safe = channels_.fail_safe_active(),
                      .side_camera = tracked && side_used,
                      .recording = recorder_ != nullptr && recorder_->recording(),
                      .outputs_enabled = enabled,
                      .camera_connected = connected,
                      .model_mismatch = settings_.model_mismatch,
                      .source = source});
}

std::uint32_t Pipeline::voice_state(std::int64_t now_ns, VoiceState& state, bool& heard) const {
  heard = false;
  if (!voice_) return 0;
  const std::uint32_t version = voice_->latest(state);
  heard = version > 0 && now_ns - state.heard_ns <= std::chrono::nanoseconds(settings_.voice_timeout).count();
  return version;
}

DriveSignals Pipeline::voice_signals(const VoiceState& state) {
  // A calibrate command re-centres the profile on the processing thread; the voice follows it.
  if (const std::uint32_t version = recentred_.version(); version != output_profile_version_) {
    output_profile_version_ = version;
    recentred_.read(output_profile_);
  }
  MouthMeasures measures;
  measures.open = state.measures[static_cast<std::size_t>(VoiceTarget::kOpen)];
  measures.width_fit = state.measures[static_cast<std::size_t>(VoiceTarget::kWidth)];
  measures.protrusion_3d = state.measures[static_cast<std::size_t>(VoiceTarget::kProtrusion)];
  measures.seal = state.measures[static_cast<std::size_t>(VoiceTarget::kSeal)];
  DriveSignals signals = drive_signals(measures, {}, output_profile_);
  signals[Signal::kTracking] = 0;
  return signals;
}

void Pipeline::output_loop() {
  FrameResult result;
  DriveFrame frame;
  VoiceState voice;
  DriveSignals voice_drive;
  std::uint32_t seen = 0, voice_seen = 0;
  DriveSource source = DriveSource::kFailSafe;
  const auto tick = std::chrono::nanoseconds(settings_.output_tick);
  std::uint64_t processed_before = 0;
  std::int64_t fps_since_ns = monotonic_ns();
  bool connected = true, enabled = true;
  while (!stop_outputs_.load(std::memory_order_relaxed)) {
    // While the voice drives, each new prediction is a drive frame; a returning face still
    // shows within one prediction (10 ms).
    if (source == DriveSource::kVoice)
      voice_->wait_newer(voice_seen, tick);
    else
      results_.wait_newer(seen, tick);
    const std::uint32_t version = results_.read(result);
    frame.new_result = version != seen;
    seen = version;
    const std::int64_t now = monotonic_ns();
    output_heartbeat_ns_.store(now, std::memory_order_relaxed);
    if (frame.new_result && version > 0) output_latency_.add(now - result.capture_time_ns);

    for (int i = 0; i < channels_.size(); ++i)
      channels_.set_override(i, control_.overrides[static_cast<std::size_t>(i)].load(std::memory_order_relaxed));
    enabled = control_.outputs_enabled.load(std::memory_order_relaxed) &&
              control_.enable_switch_closed.load(std::memory_order_relaxed);
    // A tracked result stops counting as tracking the moment the camera goes away or stops
    // delivering, not when the processing thread next publishes: the hold time starts there.
    connected = capture_.connected();
    // Three frame periods: a late frame is not a loss, a camera that stopped delivering is.
    const bool tracked = result.tracked && connected && now - result.capture_time_ns <= 3 * frame_period_ns();
    bool heard = false;
    const std::uint32_t voice_version = voice_state(now, voice, heard);
    const DriveSource before = source;
    source = select_source(tracked, heard);
    const bool new_voice = source == DriveSource::kVoice && voice_version != voice_seen;
    // The voice takes over with its newest prediction, not the one it last drove with.
    if (new_voice || (source == DriveSource::kVoice && before != DriveSource::kVoice))
      voice_drive = voice_signals(voice);
    voice_seen = voice_version;
    const DriveSignals& signals = hand_over_.step(source, result.signals, voice_drive, now);
    channels_.step(signals, {.tracked = tracked,
                             .voice = source == DriveSource::kVoice,
                             .enabled = enabled,
                             .now_ns = now,
                             .frame_time_ns = source == DriveSource::kVoice ? voice.heard_ns : result.capture_time_ns});

    // Frames per second over the last second or so.
    if (now - fps_since_ns >= 1'000'000'000) {
      const std::uint64_t processed = processed_.load(std::memory_order_relaxed);
      frame.fps = static_cast<float>(static_cast<double>(processed - processed_before) * 1e9 /
                                     static_cast<double>(now - fps_since_ns));
      processed_before = processed;
      fps_since_ns = now;
    }
    frame.status = status(tracked, result.side_used, connected, enabled, source);
    frame.sequence = result.sequence;
    frame.capture_time_ns = result.capture_time_ns;
    frame.signals = source == DriveSource::kFailSafe ? DriveSignals{} : signals;
    frame.timecode = version > 0 ? result.timecode : -1;  // before the first result the seqlock holds zeros
    if (timecode_) frame.timecode_rate = timecode_->rate();
    frame.latency_ms = static_cast<float>(ms(result.processed_time_ns - result.capture_time_ns));
    fill(frame, now);
    for (Output* output : outputs_) output->publish(frame);
    if (new_voice) voice_latency_.add(monotonic_ns() - voice.heard_ns);
  }
  // A reload's stop: the outputs keep the last frame they got, and the next pipeline's drive
  // carries on from it.
  std::atomic_thread_fence(std::memory_order_acquire);  // pairs with stop()'s store of stop_outputs_
  if (leave_where_it_is_.load(std::memory_order_relaxed)) return;
  // The last thing every output sees: the neutral pose.
  channels_.reset_to_neutral();
  frame.new_result = false;
  frame.signals = DriveSignals{};
  frame.status = status(false, false, connected, enabled, DriveSource::kFailSafe);
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
  const CaptureCounters capture = capture_.counters();
  PipelineStats s;
  s.captured = capture.captured;
  s.processed = processed_.load(std::memory_order_relaxed);
  s.tracked = tracked_.load(std::memory_order_relaxed);
  s.dropped = capture.dropped;
  s.lost_track = lost_track_.load(std::memory_order_relaxed);
  s.warmed = warmed_.load(std::memory_order_relaxed);
  s.disconnects = capture.disconnects;
  s.corrupt = capture.corrupt;
  s.processed_median_ms = processed_latency_.quantile_ms(0.5);
  s.processed_p99_ms = processed_latency_.quantile_ms(0.99);
  s.output_median_ms = output_latency_.quantile_ms(0.5);
  s.output_p99_ms = output_latency_.quantile_ms(0.99);
  s.voice_median_ms = voice_latency_.quantile_ms(0.5);
  s.voice_p99_ms = voice_latency_.quantile_ms(0.99);
  s.voice_frames = voice_latency_.count();
  const auto stage = [](const LatencyHistogram& h) {
    return PipelineStats::Stage{h.quantile_ms(0.5), h.quantile_ms(0.99)};
  };
  s.hand_off = stage(hand_off_time_);
  s.landmarks = stage(landmarks_time_);
  s.fit = stage(fit_time_);
  s.measures = stage(measures_time_);
  const std::int64_t end_ns = stop_ns_ > 0 ? stop_ns_.load() : monotonic_ns();
  s.seconds = start_ns_ > 0 ? static_cast<double>(end_ns - start_ns_) / 1e9 : 0;
  s.connected = capture_.connected();
  return s;
}

}  // namespace lipdrive
