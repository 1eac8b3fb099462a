// The Modbus outputs (DESIGN.md 5): a server that exposes the drive through one register map
// (docs/modbus-register-map.md, the same for TCP and RTU), and a client that writes channels
// to holding registers of a remote slave.
//
// Thread model: publish() runs on the pipeline's output thread and only stores the frame in
// a seqlock. Each output has one thread of its own that owns its libmodbus context and reads
// the newest frame from the seqlock; network or serial I/O never reaches publish().
#pragma once

#include "core/drive_channels.hpp"
#include "drivers/modbus_link.hpp"
#include "drivers/modbus_server.hpp"
#include "firmware_app/config.hpp"
#include "firmware_app/drive_output.hpp"
#include "firmware_app/latency_histogram.hpp"
#include "firmware_app/latest_frame.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <vector>

namespace lipdrive {

/// Register addresses (0-based, as on the wire) of docs/modbus-register-map.md.
namespace modbus_map {
// Input registers (function 4).
inline constexpr int kStatus = 0;          // StatusBit
inline constexpr int kHeartbeat = 1;       // DriveFrame::counter, low 16 bits
inline constexpr int kSequenceHigh = 2;    // DriveFrame::sequence, low 32 bits, high word first
inline constexpr int kSequenceLow = 3;
inline constexpr int kLatencyUsHigh = 4;   // capture -> processed, µs, 32 bits, high word first
inline constexpr int kLatencyUsLow = 5;
inline constexpr int kFpsTenths = 6;       // processed frames per second × 10
inline constexpr int kChannelCount = 7;
inline constexpr int kFirstChannel = 16;   // one register per channel, ChannelBank order
// Holding registers (functions 3, 6, 16, 22, 23).
inline constexpr int kOutputEnable = 0;    // 0 off, anything else on
inline constexpr int kCalibrate = 1;       // write 1: calibrate neutral; reads 0
inline constexpr int kRecord = 2;          // write 1 start / 0 stop; reads 1 while recording
inline constexpr int kFirstOverride = 16;  // one register per channel
inline constexpr std::uint16_t kNoOverride = 0xFFFF;
}  // namespace modbus_map

/// A value in output units as a register: rounded, clamped to 0..65535.
std::uint16_t to_register(double value);

/// Serves the register map. Control registers write `control`; the channel and status
/// registers show the newest published DriveFrame.
class ModbusServerOutput : public Output {
 public:
  /// Binds the port or opens the serial device at once: throws std::runtime_error when that
  /// fails, std::invalid_argument for more than kMaxChannels channels. `control` must outlive
  /// the output.
  ModbusServerOutput(const ModbusServerOptions& options, std::span<const ChannelSpec> channels,
                     DriveControl& control);

  void publish(const DriveFrame& frame) override { latest_.publish(frame); }
  std::string describe() const override { return "modbus server " + server_.describe(); }
  bool healthy() const override { return server_.healthy(); }

  /// TCP: the port actually bound (options.link.port 0 picks a free one).
  int port() const { return server_.port(); }
  std::uint64_t requests() const { return server_.requests(); }

 private:
  // Both run on the server thread.
  void refresh(std::span<std::uint16_t> input, std::span<std::uint16_t> holding) const;
  void written(int address, std::span<const std::uint16_t> values);

  int channel_count_;
  DriveControl& control_;
  DriveFrame neutral_frame_;  // what the registers show until the first frame is published
  Published<DriveFrame> latest_;
  ModbusServer server_;  // last: its thread uses the members above
};

/// Writes chosen channels (uint16, output units) to consecutive holding registers of a remote
/// slave, at most rate_hz times a second and only when a newer frame exists. A failed
/// request drops the connection; reconnection backs off exponentially up to max_backoff_ms.
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
  ModbusClient client_;  // the thread's
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
