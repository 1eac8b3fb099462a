// The daemon's bounded-latency frame path (docs/data-flow.md): three threads.
//
//   capture thread     owns the FrameSource; copies each frame into a latest-frame-wins
//                      hand-off (capture.hpp)
//   processing thread  takes the newest frame; tracker, fit, measures (FrameProcessor), the
//                      side camera's protrusion, the performer's calibration -> DriveSignals;
//                      publishes a FrameResult; acts on calibrate requests
//   output thread      picks the source that drives (the tracked face, else the voice of the
//                      VoiceRoom while it is heard, else the fail-safe) and cross-fades
//                      between video and voice (core/drive_source.hpp); steps the drive
//                      channels (smoothing, ranges, fail-safe, slew) on every new result (every
//                      new voice prediction while the voice drives) and at least every
//                      output_tick, assembles the status word and hands the DriveFrame to
//                      every output
//
// The output thread stays because the face detector holds the processing thread for tens of ms
// per frame while it re-acquires a lost face, and the fail-safe must still tick every 20 ms.
//
// A frame that arrives while the previous one is still being processed replaces the waiting
// one instead of queueing behind it, so latency stays bounded when the CPU is briefly busy.
// The processing path allocates nothing per frame once the face is tracked.
#pragma once

#include "core/calibration.hpp"
#include "core/drive_channels.hpp"
#include "core/drive_source.hpp"
#include "drivers/cpu_latency.hpp"
#include "drivers/frame_source.hpp"
#include "firmware_app/daemon/capture.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "firmware_app/daemon/frame_result.hpp"
#include "firmware_app/daemon/latency_histogram.hpp"
#include "firmware_app/daemon/latest_frame.hpp"
#include "firmware_app/daemon/log_throttle.hpp"
#include "firmware_app/daemon/preview_feed.hpp"
#include "firmware_app/daemon/side_camera.hpp"
#include "firmware_app/daemon/take_recorder.hpp"
#include "firmware_app/daemon/timecode_source.hpp"
#include "firmware_app/daemon/voice_room.hpp"
#include "firmware_app/outputs/output.hpp"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace lipdrive {

struct PipelineSettings {
  std::chrono::milliseconds frame_wait{100};  // how long the processing thread waits for a frame
  std::uint64_t max_frames = 0;               // finished() after this many processed frames; 0 = never
  /// sd_notify("WATCHDOG=1") from the processing loop at most this often; 0 = off.
  std::chrono::microseconds watchdog_interval{0};
  /// The drive: channels and their safety layer; the outputs see them every result and at
  /// least every output_tick.
  std::vector<ChannelSpec> channels;
  SafetySettings safety;
  std::chrono::milliseconds output_tick{20};
  int neutral_frames = 30;      // tracked frames of a calibrate command's neutral capture
  /// The frame path's threads (capture, side capture, processing, output) under SCHED_FIFO at
  /// this priority, 1..99; 0 = the normal scheduler.
  int realtime_priority = 0;
  /// While the frame path runs, the CPUs wake from idle within this many microseconds
  /// (drivers/cpu_latency.hpp); -1 = the system's idle states.
  int cpu_latency_us = -1;
  /// This long before the next frame is due (the last one's capture time plus the last interval
  /// between frames), the processing thread reads the landmark predictor's data into the cache
  /// (FrameProcessor::warm); 0 = never.
  std::chrono::microseconds warm_ahead{2000};
  bool model_mismatch = false;  // reported in the status word (kStatusModelMismatch)
  /// [voice]: the cross-fade between video and voice; no sound for voice_timeout: the voice is gone.
  std::chrono::milliseconds voice_crossfade{150}, voice_timeout{200};
};

struct PipelineStats {
  std::uint64_t captured = 0, processed = 0, tracked = 0;
  std::uint64_t dropped = 0;                             // frames replaced by a newer one before processing
  std::uint64_t lost_track = 0;                          // times a tracked face was lost
  std::uint64_t warmed = 0;                              // frames whose landmark data was read into the cache before they came (warm_ahead)
  std::uint64_t disconnects = 0;                         // times the source went away after delivering frames
  std::uint64_t corrupt = 0;                             // frames the source could not decode
  double processed_median_ms = 0, processed_p99_ms = 0;  // capture -> processed
  double output_median_ms = 0, output_p99_ms = 0;        // capture -> output thread
  /// While the voice drives: the end of the newest sound block -> the drive frame written to the
  /// outputs (serial and GPIO write inline); the model's look-ahead comes on top.
  double voice_median_ms = 0, voice_p99_ms = 0;
  std::uint64_t voice_frames = 0;  // drive frames the voice drove
  /// Where capture -> processed goes, stage by stage (median, p99 in ms): the wait of a captured
  /// frame for the processing thread, then the frame processor's three stages.
  struct Stage {
    double median_ms = 0, p99_ms = 0;
  };
  Stage hand_off, landmarks, fit, measures;
  double seconds = 0;              // since start()
  bool connected = true;           // the source currently delivers
};

class Pipeline {
 public:
  /// `control` carries the commands of the outputs and of the daemon to the drive: it is the
  /// owner's, and outlives the pipeline and every output that writes it.
  Pipeline(std::unique_ptr<FrameSource> source, std::unique_ptr<FrameProcessor> processor, PipelineSettings settings,
           DriveControl& control);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  // Before start(). What is passed by reference is not owned and must outlive the pipeline.
  /// Where drive frames go (output thread).
  void add_output(Output& output) { outputs_.push_back(&output); }
  /// Where results go (processing thread).
  void add_sink(ResultSink& sink) { sinks_.push_back(&sink); }
  /// The take recorder: a sink whose state the status word reports.
  void set_recorder(TakeRecorder& recorder) {
    recorder_ = &recorder;
    add_sink(recorder);
  }
  /// The side camera, paired with front frames by capture time.
  void set_side_camera(std::unique_ptr<SideCamera> side) { side_ = std::move(side); }
  /// The timecode every frame is stamped with (processing thread).
  void set_timecode(const TimecodeSource& timecode) { timecode_ = &timecode; }
  /// [voice]: the voice that drives while the face is lost (read by both threads).
  void set_voice(VoiceRoom& voice) { voice_ = &voice; }
  /// Where the monitor's previews go (processing thread, at the feed's own rate).
  void set_preview(PreviewFeed& preview) { preview_ = &preview; }
  /// The performer profile the processing thread applies.
  void set_profile(const PerformerProfile& profile);

  /// Before start(): the drive carries on from where a stopped pipeline left it
  /// (ChannelBank::carry_on), for a reload.
  void carry_on(const ChannelBankState& state) { channels_.carry_on(state); }

  void start();
  /// How a stop leaves the figure: at the neutral pose (the daemon stops), or where it is, for
  /// the pipeline of a reload to carry on from (channel_state()).
  enum class Leave { kNeutral, kWhereItIs };
  /// Finishes the frame in hand, gives the outputs the neutral pose (or, kWhereItIs, nothing
  /// more), joins all threads. A second call does nothing more.
  void stop(Leave leave = Leave::kNeutral);
  /// Once stopped: where the drive stands, as the outputs last got it.
  ChannelBankState channel_state() const { return channels_.state(); }

  /// max_frames processed, the recording ended, or the source failed for good.
  bool finished() const { return finished_.load(std::memory_order_acquire); }
  bool failed() const { return capture_.failed(); }

  PipelineStats stats() const;
  /// The latest result and its version (0: none yet); lock-free.
  std::uint32_t latest(FrameResult& result) const { return results_.read(result); }
  /// The latest drive frame and its version (0: none yet); lock-free.
  std::uint32_t latest_drive(DriveFrame& frame) const { return drive_frames_.read(frame); }
  /// The profile the last calibrate command re-centred, and its version (0: none yet), for
  /// the owner to save; lock-free.
  std::uint32_t recentred_profile(PerformerProfile& profile) const { return recentred_.read(profile); }
  const std::string& describe_source() const { return capture_.describe(); }
  /// The side camera, or nullptr without one.
  const SideCamera* side_camera() const { return side_.get(); }

  /// Commands to the drive (output enable, overrides, calibrate, record); any thread.
  DriveControl& control() { return control_; }

 private:
  void processing_loop();
  void output_loop();
  void process(const CapturedFrame& frame);
  /// Processing thread: a frame whose measuring threw (a library's error on a picture it
  /// cannot handle, memory exhausted) is published untracked, so that the drive holds and eases
  /// to neutral while such errors go on, and the next frame detects the face afresh; one that
  /// threw after its result was published (in a sink or the preview) only logs. The thread
  /// carries on either way. At most ten lines a second.
  void untrust(const CapturedFrame& frame, const char* what);
  /// Processing thread: the frame's source of the drive, the counts, then the result to readers.
  void publish(FrameResult& result);
  /// Processing thread: a new calibrate request starts a neutral capture; the tracked frames
  /// feed it; the last of settings_.neutral_frames re-centres the profile on them.
  void calibrate_step(const FrameResult& result);
  /// Output thread: the status word of the drive frame being assembled.
  std::uint16_t status(bool tracked, bool side_used, bool connected, bool enabled, DriveSource source) const;
  /// Either thread: the newest voice prediction and its version; `heard`: its sound is recent.
  std::uint32_t voice_state(std::int64_t now_ns, VoiceState& state, bool& heard) const;
  /// Output thread: the voice's measures as drive signals through the performer's profile.
  DriveSignals voice_signals(const VoiceState& state);
  /// Completes a drive frame from the channel bank and publishes it for readers.
  void fill(DriveFrame& frame, std::int64_t now_ns);
  void ping_watchdog(std::int64_t now_ns);
  /// Processing thread: when to warm the caches for the frame after the one captured at
  /// `capture_ns`; 0 = not at all.
  std::int64_t warm_time(std::int64_t capture_ns);
  /// The front camera's frame period as its stream runs now (30 fps where it states none).
  std::int64_t frame_period_ns() const;

  Capture capture_;
  std::unique_ptr<FrameProcessor> processor_;
  std::unique_ptr<SideCamera> side_;
  PipelineSettings settings_;
  std::vector<Output*> outputs_;
  std::vector<ResultSink*> sinks_;
  const TakeRecorder* recorder_ = nullptr;
  const TimecodeSource* timecode_ = nullptr;
  PreviewFeed* preview_ = nullptr;
  VoiceRoom* voice_ = nullptr;

  Published<FrameResult> results_;
  Published<DriveFrame> drive_frames_;
  Published<PerformerProfile> recentred_;
  DriveControl& control_;
  std::atomic<bool> calibrated_{false};  // the profile in use is the performer's (status word)

  // Processing thread's.
  PerformerProfile profile_;
  CalibrationCapture neutral_;  // a calibrate command's neutral frames
  bool capturing_neutral_ = false;
  LogThrottle frame_errors_;  // untrust()'s lines
  bool published_ = false;    // the frame in hand's result went to readers
  std::uint32_t calibrate_requests_seen_ = 0;
  std::int64_t last_watchdog_ns_ = 0;
  std::int64_t warm_at_ns_ = 0;       // when to warm the caches for the next frame; 0: not before it
  std::int64_t last_capture_ns_ = 0;  // of the last frame processed
  bool was_tracked_ = false;

  ChannelBank channels_;             // output thread's
  HandOver hand_over_;               // output thread's
  PerformerProfile output_profile_;  // output thread's: the voice's measures -> signals
  std::uint32_t output_profile_version_ = 0;
  LatencyHistogram processed_latency_, output_latency_, voice_latency_;
  LatencyHistogram hand_off_time_, landmarks_time_, fit_time_, measures_time_;  // processing thread's stages

  std::atomic<std::uint64_t> processed_{0}, tracked_{0}, lost_track_{0}, warmed_{0};
  std::atomic<bool> finished_{false};
  std::atomic<bool> stop_processing_{false}, stop_outputs_{false};
  std::atomic<bool> leave_where_it_is_{false};        // stop()'s Leave, stored before stop_outputs_
  std::atomic<std::int64_t> output_heartbeat_ns_{0};  // the output thread's last round
  std::int64_t start_ns_ = 0;
  std::atomic<std::int64_t> stop_ns_{0};

  std::thread processing_thread_, output_thread_;
  CpuLatencyRequest cpu_latency_;  // held from start() to stop()
};

}  // namespace lipdrive
