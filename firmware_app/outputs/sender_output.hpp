// The base of every output that sends drive frames to a peer over a link that can block or go
// away (a Modbus slave, olad, ...): the frames cross to a thread of its own, which sends the
// newest one at most rate_hz times a second, retries a failed peer with the one back-off
// (core/backoff.hpp) and sends the pipeline's last frame (the neutral pose; at a reload the
// figure where it is) before it stops,
// unless a peer it waits for failed its last attempt (a stop is not held for another timeout).
//
// Thread model: publish() runs on the pipeline's output thread and only stores the frame in a
// seqlock; a slow or absent peer never reaches it. The sender thread owns the link: it alone
// calls send() and close(). A derived class calls start() as the last step of its constructor
// and stop() as the first step of its destructor, so the thread never sees a half-built or
// half-destroyed object.
#pragma once

#include "core/backoff.hpp"
#include "firmware_app/daemon/latency_histogram.hpp"
#include "firmware_app/daemon/latest_frame.hpp"
#include "firmware_app/outputs/output.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace lipdrive {

class SenderOutput : public Output {
 public:
  void publish(const DriveFrame& frame) final { latest_.publish(frame); }
  void request_stop() final;
  std::string describe() const final { return description_; }
  bool healthy() const final { return healthy_.load(std::memory_order_relaxed); }
  /// Capture -> sent (send() returned true), once per captured frame.
  const LatencyHistogram* wire_latency() const final { return &wire_latency_; }

  std::uint64_t sends_ok() const { return sends_ok_.load(std::memory_order_relaxed); }
  /// Attempts that failed (the peer was absent, refused or did not answer).
  std::uint64_t sends_failed() const { return sends_failed_.load(std::memory_order_relaxed); }

 protected:
  SenderOutput(std::string description, int rate_hz, std::chrono::milliseconds max_backoff);
  void start();
  /// request_stop(), then joins the thread: it sends the newest frame first if that has not
  /// gone out yet (see send_waits_for_peer()).
  void stop();

  /// Sender thread: puts `frame` on the link, (re)connecting first when needed. False when
  /// it failed; failure() says why.
  virtual bool send(const DriveFrame& frame) = 0;
  virtual std::string failure() const = 0;
  /// Sender thread, once the loop has ended: let go of the link.
  virtual void close() {}
  /// Whether send() waits for the peer's answer, up to the link's timeout (a Modbus slave);
  /// then a peer that failed its last attempt is not sent the neutral pose at stop. A send that
  /// does not wait (DMX, OSC) is always tried once more.
  virtual bool send_waits_for_peer() const { return false; }

 private:
  void run();
  bool send_counted(const DriveFrame& frame);
  /// Sleeps until `deadline_ns` (monotonic) or stop(); false on stop().
  bool sleep_until(std::int64_t deadline_ns);

  std::string description_;
  std::int64_t period_ns_;
  Backoff backoff_;                          // the thread's
  std::uint64_t last_sequence_on_wire_ = 0;  // the thread's
  Published<DriveFrame> latest_;
  LatencyHistogram wire_latency_;
  std::atomic<std::uint64_t> sends_ok_{0}, sends_failed_{0};
  std::atomic<bool> healthy_{false};
  std::mutex stop_mutex_;  // only for the stop wake-up; publish() never takes it
  std::condition_variable stop_wake_;
  bool stopping_ = false;  // under stop_mutex_
  std::thread thread_;
};

}  // namespace lipdrive
