// [[outputs.serial]]: drive channels over a serial line, as framed binary, text lines or
// Pololu Maestro Set Target commands (docs/serial-protocol.md, docs/maestro.md).
//
// Thread model: publish() runs on the pipeline's output thread and is the only caller that
// touches the port; healthy(), counters() and latency() read atomics from any thread.
// Everything publish() does is non-blocking, so no thread of its own is needed: the write
// takes what fits and returns, and while the port is gone a reopen is attempted from
// publish() once its back-off delay (core/backoff.hpp) has passed (open(O_NONBLOCK) + tcsetattr; a missing
// device fails at once, a reappearing USB adapter costs one open of a few ms per outage).
//
// Latest value wins: nothing is queued in user space. A frame is written whole or not at
// all; only when the kernel takes part of one is its tail kept and finished on the next
// publish(), so receivers never see a torn frame. Frames arriving while a tail is pending,
// while the kernel already holds a frame's worth of unsent bytes, or while the port is
// gone are dropped and counted.
#pragma once

#include "core/backoff.hpp"
#include "core/drive_channels.hpp"
#include "drivers/serial_port.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/daemon/latency_histogram.hpp"
#include "firmware_app/outputs/output.hpp"

#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace lipdrive {

struct SerialOutputCounters {
  std::uint64_t written = 0;  // frames whose last byte reached the kernel
  std::uint64_t dropped = 0;  // frames not written because the line was busy
  std::uint64_t offline = 0;  // frames not written because the port was gone
  std::uint64_t reopens = 0;  // times the port came back after an outage
};

class SerialOutput final : public Output {
 public:
  /// Picks the channels (framed, line: options.channels by name, empty = all; maestro:
  /// options.servos) and opens the port. Throws std::invalid_argument for an unknown channel
  /// name (naming it), invalid line settings, a line-mode name containing ' ', '=' or a line
  /// break, or a Maestro servo outside 0..23, used twice, or on a channel whose output range
  /// is not a pulse width in µs within (0, 4095.75]. A port that cannot be opened is not an
  /// error: the output starts unhealthy and keeps retrying.
  SerialOutput(const SerialOutputOptions& options, std::span<const ChannelSpec> channels);

  void publish(const DriveFrame& frame) override;
  /// Retries for up to 200 ms where publish() would drop the frame: the neutral pose on stop.
  void publish_last(const DriveFrame& frame) override;
  std::string describe() const override { return description_; }
  bool healthy() const override { return healthy_.load(std::memory_order_relaxed); }

  SerialOutputCounters counters() const;
  /// Capture (DriveFrame::capture_time_ns) -> last byte written, for frames carrying a new result.
  const LatencyHistogram* wire_latency() const override { return &latency_; }

 private:
  std::size_t encode(const DriveFrame& frame);
  /// Writes what the kernel takes of the pending bytes; true when none are left.
  bool write_pending();
  bool reopen_due(std::int64_t now_ns);
  void try_open(std::int64_t now_ns);
  void begin_outage(const std::string& reason, std::int64_t now_ns);

  const SerialOutputOptions::Mode mode_;
  const SerialPortSettings settings_;
  const std::string description_;
  std::vector<int> channel_indices_;  // into DriveFrame::values, in wire order
  std::vector<std::string> names_;    // line mode: the channel names, in wire order
  std::vector<int> servos_;           // maestro: servo number per picked channel
  std::vector<double> picked_;        // this frame's values of the picked channels
  std::vector<std::uint8_t> buffer_;  // sized once for the longest encoding of the mode

  std::unique_ptr<SerialPort> port_;                 // null while the port is gone
  std::size_t pending_begin_ = 0, pending_end_ = 0;  // unwritten bytes of the last frame in buffer_
  std::int64_t pending_capture_ns_ = 0;              // its capture time; 0 = an idle tick
  std::uint32_t pending_counter_ = 0;                // its DriveFrame::counter
  std::uint32_t last_written_counter_ = 0;           // of the last frame written whole
  bool in_outage_ = false;
  std::int64_t outage_start_ns_ = 0;
  std::uint64_t offline_at_outage_start_ = 0;
  Backoff backoff_;  // reopening while the port is gone
  std::int64_t next_open_ns_ = 0;

  std::atomic<bool> healthy_{false};
  std::atomic<std::uint64_t> written_{0}, dropped_{0}, offline_{0}, reopens_{0};
  LatencyHistogram latency_;
};

}  // namespace lipdrive
