// [[outputs.modbus_client]] (docs/data-flow.md): writes chosen channels to holding registers of a
// remote Modbus slave (a PLC, a servo drive).
//
// Thread model: publish() runs on the pipeline's output thread and only stores the frame in a
// seqlock. The output's own thread owns the libmodbus context, takes the newest frame from the
// seqlock and writes it; a slow or absent slave never reaches publish().
#pragma once

#include "core/backoff.hpp"
#include "core/drive_channels.hpp"
#include "drivers/modbus_link.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/daemon/latency_histogram.hpp"
#include "firmware_app/daemon/latest_frame.hpp"
#include "firmware_app/outputs/output.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <vector>

namespace lipdrive {

/// Writes the channels (uint16, output units, modbus_registers.hpp's to_register) to
/// consecutive holding registers, at most rate_hz times a second and only when a newer frame
/// exists. A failed request drops the connection; reconnection backs off exponentially
/// (core/backoff.hpp) up to max_backoff_ms.
class ModbusClientOutput : public Output {
 public:
  /// Throws std::invalid_argument naming an unknown channel, or when the channels do not fit
  /// in one write request (123 registers) or the 16-bit address space.
  ModbusClientOutput(const ModbusClientOptions& options, std::span<const ChannelSpec> channels);
  /// Writes the newest frame if it has not gone out yet (the pipeline's last one is the
  /// neutral pose), then stops; waits at most about two timeouts.
  ~ModbusClientOutput() override;

  void publish(const DriveFrame& frame) override { latest_.publish(frame); }
  std::string describe() const override { return description_; }
  bool healthy() const override { return connected_.load(std::memory_order_relaxed); }

  std::uint64_t writes_ok() const { return writes_ok_.load(std::memory_order_relaxed); }
  /// Attempts that failed: the slave did not answer, answered with an exception, or could
  /// not be connected to.
  std::uint64_t writes_failed() const { return writes_failed_.load(std::memory_order_relaxed); }
  /// Capture -> on the wire (the write acknowledged), once per captured frame.
  const LatencyHistogram* wire_latency() const override { return &wire_latency_; }

 private:
  void run();
  bool write(const DriveFrame& frame);
  /// Sleeps until `deadline_ns` (monotonic) or destruction; false on destruction.
  bool sleep_until(std::int64_t deadline_ns);

  ModbusClientOptions options_;
  std::vector<int> channel_indices_;  // DriveFrame::values index per register
  std::string description_;
  ModbusClient client_;                      // the thread's
  Backoff backoff_;                          // the thread's
  std::uint64_t last_sequence_on_wire_ = 0;  // the thread's
  Published<DriveFrame> latest_;
  LatencyHistogram wire_latency_;
  std::atomic<std::uint64_t> writes_ok_{0}, writes_failed_{0};
  std::atomic<bool> connected_{false};
  std::mutex stop_mutex_;  // only for the stop wake-up; publish() never takes it
  std::condition_variable stop_wake_;
  bool stopping_ = false;  // under stop_mutex_
  std::thread thread_;     // last: it uses the members above
};

}  // namespace lipdrive
