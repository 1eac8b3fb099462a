// A camera's capture thread (docs/data-flow.md, the first step of the frame path): the thread owns
// the FrameSource, waits in grab() and copies every frame it delivers into a
// latest-frame-wins hand-off (latest_frame.hpp). It never waits for the consumer and never
// queues: a frame the consumer has not taken when the next one arrives is replaced (and
// counted as dropped). The pipeline runs one for the front camera, SideCamera one for the side.
//
// Thread model: start() and stop() come from the owner; the capture thread is the only caller
// of the FrameSource and the only writer of the hand-off; take() belongs to one consumer
// thread; the counters and the state flags are atomics any thread may read.
#pragma once

#include "drivers/frame_source.hpp"
#include "firmware_app/daemon/latest_frame.hpp"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <thread>

namespace lipdrive {

/// A frame in the hand-off: the capture thread's copy of the source's luma and Cr planes.
struct CapturedFrame {
  cv::Mat gray;  // keeps its buffer while the frame size does not change
  cv::Mat cr;    // the same; empty from a monochrome camera
  std::int64_t capture_time_ns = 0;
  std::uint64_t sequence = 0;
  double media_time_s = 0;
};

struct CaptureCounters {
  std::uint64_t captured = 0;     // frames handed over
  std::uint64_t dropped = 0;      // frames replaced by a newer one before the consumer took them
  std::uint64_t disconnects = 0;  // times the source went away after delivering frames
  std::uint64_t corrupt = 0;      // frames the source could not decode
};

class Capture {
 public:
  /// Log lines start with `role` and the source's description ("side camera /dev/video2"; no
  /// role: the description alone); `when_lost` ends the lines about a camera that went away or
  /// failed (what the daemon does meanwhile).
  Capture(std::unique_ptr<FrameSource> source, std::string_view role, std::string when_lost);
  ~Capture();
  Capture(const Capture&) = delete;
  Capture& operator=(const Capture&) = delete;

  /// Starts the capture thread, named `thread_name`, under SCHED_FIFO at `realtime_priority`
  /// (0: the normal scheduler). Returns "" or why the priority was refused (the thread runs).
  std::string start(const char* thread_name, int realtime_priority);
  /// Joins the thread; grab() returns at least every grab_timeout, so this is prompt.
  void stop();

  /// The consumer: the newest frame, or nullptr when none arrives within `timeout`. The frame
  /// stays the consumer's until its next take().
  const CapturedFrame* take(std::chrono::nanoseconds timeout) { return frames_.take(timeout); }

  /// No disconnect since the last frame (true from the start, until the source reports one:
  /// a camera not there at start does with its first grab, though it is not counted as one),
  /// and a frame within kSilentAfter: a camera that stops sending without an error (a cable
  /// glitch, a stream that stalls) is not connected either.
  bool connected() const {
    return connected_.load(std::memory_order_relaxed) && !silent_.load(std::memory_order_relaxed);
  }
  /// Frames are flowing: some arrived, and since the last one no disconnect, end or failure.
  bool delivering() const {
    return connected() && captured_.load(std::memory_order_relaxed) > 0 && !ended() && !failed();
  }
  /// A recording ended, or the source threw: no frame will come any more.
  bool ended() const { return ended_.load(std::memory_order_acquire); }
  bool failed() const { return failed_.load(std::memory_order_acquire); }
  /// CLOCK_MONOTONIC of the last return from grab(): the thread is alive (watchdog).
  std::int64_t heartbeat_ns() const { return heartbeat_ns_.load(std::memory_order_relaxed); }
  CaptureCounters counters() const;

  /// The source's frame rate as its stream last opened: a camera that was not there at start
  /// reports the rate asked for until it opens, and one that comes back may run at another.
  double frame_rate() const { return frame_rate_.load(std::memory_order_relaxed); }
  /// The source's description, e.g. "/dev/video0".
  const std::string& describe() const { return description_; }
  /// What log lines start with: the role and the description.
  const std::string& name() const { return name_; }

  static constexpr std::chrono::milliseconds kGrabTimeout{100};  // how often the thread looks up from grab()
  static constexpr std::chrono::milliseconds kSilentAfter{1000};  // no frame this long: reported, not connected

 private:
  void run();

  std::unique_ptr<FrameSource> source_;
  const std::string description_, name_, when_lost_;
  std::atomic<double> frame_rate_;  // written by the capture thread on every (re)connection
  LatestFrame<CapturedFrame> frames_;
  std::atomic<bool> connected_{true}, silent_{false}, ended_{false}, failed_{false}, stop_{false};
  std::atomic<std::int64_t> heartbeat_ns_{0};
  std::atomic<std::uint64_t> captured_{0}, disconnects_{0}, corrupt_{0};
  std::thread thread_;  // last: it uses everything above
};

}  // namespace lipdrive
