// The daemon's bounded-latency pipeline (DESIGN.md 2): three threads.
//
//   capture thread     owns the FrameSource; copies each frame into a LatestFrame slot
//   processing thread  takes the newest frame, runs FrameProcessor, publishes a FrameResult
//   output thread      runs the drive channels' safety layer on every new result (and on idle
//                      ticks, so the fail-safe eases when no frame comes) and hands the
//                      DriveFrame to the outputs (Modbus, serial, GPIO)
//
// A frame that arrives while the previous one is still being processed replaces the waiting
// one instead of queueing behind it, so latency stays bounded when the CPU is briefly busy.
// The processing path allocates nothing per frame once the face is tracked.
#pragma once

#include "core/calibration.hpp"
#include "core/drive_channels.hpp"
#include "core/mouth_measures.hpp"
#include "drivers/frame_source.hpp"
#include "firmware_app/drive_output.hpp"
#include "firmware_app/frame_processor.hpp"
#include "firmware_app/latency_histogram.hpp"
#include "firmware_app/side_camera.hpp"
#include "firmware_app/latest_frame.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <thread>
#include <vector>

namespace lipdrive {

/// What the pipeline produces per frame; trivially copyable so it can cross threads through
/// a seqlock. The neutral result (default-constructed) is "not tracked, all zero".
struct FrameResult {
  std::uint64_t sequence = 0;           // the source's frame sequence number
  std::int64_t capture_time_ns = 0;     // CLOCK_MONOTONIC at capture
  std::int64_t processed_time_ns = 0;   // CLOCK_MONOTONIC when the measures were ready
  double media_time_s = 0;
  bool tracked = false;
  MouthMeasures measures;               // valid when tracked, zero otherwise
  VisemeWeights visemes{};              // FrameMeasurement::visemes when tracked, zero otherwise
  DriveSignals signals;                 // calibrated values for the drive, zero when not tracked
  bool side_used = false;               // protrusion came from the side camera (protrusion_side)
  double protrusion_side = 0;           // side-view protrusion over the nose length, when side_used
  int width = 0, height = 0;            // frame size in pixels
};

/// Sees every result on the processing thread, in order (the take recorder). push() must
/// neither block nor allocate.
class ResultSink {
 public:
  virtual ~ResultSink() = default;
  virtual void push(const FrameResult& result) = 0;
};

struct PipelineSettings {
  std::chrono::milliseconds grab_timeout{100};  // how often the capture thread looks up from grab()
  std::chrono::milliseconds frame_wait{100};    // how long the processing thread waits for a frame
  std::uint64_t max_frames = 0;                 // finished() after this many processed frames; 0 = never
  /// sd_notify("WATCHDOG=1") from the processing loop at most this often; 0 = off.
  std::chrono::microseconds watchdog_interval{0};
  /// The drive: channels and their safety layer; the outputs see them every result and at
  /// least every output_tick.
  std::vector<ChannelSpec> channels;
  SafetySettings safety;
  std::chrono::milliseconds output_tick{20};
};

struct PipelineStats {
  std::uint64_t captured = 0, processed = 0, tracked = 0;
  std::uint64_t dropped = 0;      // frames replaced by a newer one before processing
  std::uint64_t lost_track = 0;   // times a tracked face was lost
  std::uint64_t disconnects = 0;  // times the source went away
  std::uint64_t corrupt = 0;      // frames the source could not decode
  double processed_median_ms = 0, processed_p99_ms = 0;  // capture -> processed
  double output_median_ms = 0, output_p99_ms = 0;        // capture -> output thread
  double seconds = 0;             // since start()
  bool connected = true;          // the source currently delivers
};

class Pipeline {
 public:
  Pipeline(std::unique_ptr<FrameSource> source, std::unique_ptr<FrameProcessor> processor,
           PipelineSettings settings);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Before start(): where results go. Not owned; must outlive the pipeline.
  void add_output(Output& output) { outputs_.push_back(&output); }
  const std::vector<Output*>& outputs() const { return outputs_; }
  void add_sink(ResultSink& sink) { sinks_.push_back(&sink); }
  /// Before start(): the side camera, paired with front frames by capture time.
  void set_side_camera(std::unique_ptr<SideCamera> side) { side_ = std::move(side); }
  /// Any thread: fix the side camera's reference line again on the next frames.
  void recalibrate_side() {
    if (side_) side_->recalibrate();
  }

  void start();
  /// Finishes the frame in hand, gives the outputs the neutral result, joins all threads.
  void stop();

  /// max_frames processed, the recording ended, or the source failed for good.
  bool finished() const { return finished_.load(std::memory_order_acquire); }
  bool failed() const { return failed_.load(std::memory_order_acquire); }

  PipelineStats stats() const;
  /// The latest result and its version (0: none yet); lock-free.
  std::uint32_t latest(FrameResult& result) const { return results_.read(result); }
  /// The latest drive frame and its version (0: none yet); lock-free.
  std::uint32_t latest_drive(DriveFrame& frame) const { return drive_frames_.read(frame); }
  std::string describe_source() const { return source_description_; }

  /// Commands to the drive (output enable, overrides) and daemon state the outputs report.
  DriveControl& control() { return control_; }
  /// The performer profile the processing thread applies from the next frame on; any thread.
  void set_profile(const PerformerProfile& profile) { profile_.publish(profile); }

 private:
  struct CapturedFrame {
    cv::Mat gray;  // keeps its buffer while the frame size does not change
    std::int64_t capture_time_ns = 0;
    std::uint64_t sequence = 0;
    double media_time_s = 0;
  };

  void capture_loop();
  void processing_loop();
  void output_loop();
  /// Completes a drive frame from the channel bank and publishes it for readers.
  void fill(DriveFrame& frame, std::int64_t now_ns);
  void process(const CapturedFrame& frame);
  void ping_watchdog(std::int64_t now_ns);

  std::unique_ptr<FrameSource> source_;
  std::unique_ptr<FrameProcessor> processor_;
  std::unique_ptr<SideCamera> side_;
  std::int64_t half_period_ns_;  // pairing window: half the front camera's frame period
  PipelineSettings settings_;
  std::string source_description_;
  std::vector<Output*> outputs_;
  std::vector<ResultSink*> sinks_;

  LatestFrame<CapturedFrame> frames_;
  Published<FrameResult> results_;
  Published<DriveFrame> drive_frames_;
  Published<PerformerProfile> profile_;
  DriveControl control_;
  ChannelBank channels_;  // output thread's
  std::int64_t max_result_age_ns_;  // older results do not count as tracking
  LatencyHistogram processed_latency_, output_latency_;

  std::atomic<std::uint64_t> captured_{0}, processed_{0}, tracked_{0}, lost_track_{0}, disconnects_{0},
      corrupt_{0};
  std::atomic<bool> connected_{true}, source_ended_{false}, finished_{false}, failed_{false};
  std::atomic<bool> stop_processing_{false}, stop_outputs_{false};
  std::atomic<std::int64_t> capture_heartbeat_ns_{0};  // the capture loop is alive (watchdog)
  std::int64_t last_watchdog_ns_ = 0;                    // processing thread's
  bool was_tracked_ = false;                             // processing thread's
  std::int64_t start_ns_ = 0;
  std::atomic<std::int64_t> stop_ns_{0};

  std::thread capture_thread_, processing_thread_, output_thread_;
};

}  // namespace lipdrive
