// The drive side of the pipeline (docs/data-flow.md): what every output (Modbus server and client,
// serial, GPIO) receives, and the commands outputs can send back to the daemon.
#pragma once

#include "core/drive_channels.hpp"
#include "core/drive_signals.hpp"
#include "core/timecode.hpp"
#include "firmware_app/daemon/latency_histogram.hpp"
#include "firmware_app/daemon/status_word.hpp"

#include <array>
#include <atomic>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

/// One step of the drive: the channel values after the safety layer. Trivially copyable.
struct DriveFrame {
  std::uint32_t counter = 0;         // +1 per drive frame, a heartbeat for remote ends
  std::uint64_t sequence = 0;        // source frame sequence of the newest result
  std::int64_t capture_time_ns = 0;  // CLOCK_MONOTONIC capture time of that frame
  std::int64_t time_ns = 0;          // CLOCK_MONOTONIC when these values were computed
  bool new_result = false;           // false: an idle tick (no newer frame; easing goes on)
  std::uint16_t status = 0;          // StatusBit, from status_word()
  float fps = 0;                     // processed frames per second, recent
  float latency_ms = 0;              // capture -> processed of the newest result
  int channel_count = 0;
  std::array<double, kMaxChannels> values{};  // output units, ChannelBank order
  /// The calibrated signals that drive (the tracked face's, the voice's or their cross-fade,
  /// status_source()), zero under the fail-safe: for outputs that describe the face rather
  /// than drive the figure (OSC's gestures).
  DriveSignals signals;
  std::int32_t timecode = -1;  // the newest result's (FrameResult::timecode); -1: none
  TimecodeRate timecode_rate = TimecodeRate::k25;
};

/// A drive output. publish() runs on the pipeline's output thread for every new result and
/// on idle ticks (so that the fail-safe eases even when no frame arrives); the last call
/// before the pipeline stops carries the neutral values (publish_last), but for a reload, which
/// stops with the figure where it is and sends no last frame. publish() must return promptly:
/// an output whose I/O can block hands the frame to a thread of its own.
class Output {
 public:
  virtual ~Output() = default;
  virtual void publish(const DriveFrame& frame) = 0;
  /// The neutral pose when the pipeline stops: the last frame, which must not be dropped
  /// where publish() would drop a frame (a busy line). May wait, briefly and boundedly.
  virtual void publish_last(const DriveFrame& frame) { publish(frame); }
  /// After the last frame: asks a thread of the output's own to finish (send the neutral pose,
  /// let go of its link) without waiting for it; the destructor joins it. The daemon asks every
  /// output at once, so that its stop waits for the slowest output, not for the sum of them.
  virtual void request_stop() {}
  /// For logs and the status line, e.g. "modbus tcp 127.0.0.1:1502".
  virtual std::string describe() const = 0;
  /// False while the output cannot reach its peer or device (it keeps retrying by itself).
  virtual bool healthy() const { return true; }
  /// Capture -> on the wire (bytes written, registers acknowledged) for outputs that send
  /// frames somewhere; nullptr for outputs that only offer them (the Modbus server, GPIO).
  virtual const LatencyHistogram* wire_latency() const { return nullptr; }
};

/// Commands from outputs (Modbus control registers, GPIO buttons) and signals to the daemon.
/// Lock-free: any thread writes; the thread that acts on a command polls it (outputs enable
/// and overrides: the output thread; calibrate: the processing thread; record: the main thread).
struct DriveControl {
  DriveControl() {
    for (auto& value : overrides) value.store(ChannelBank::kNoOverride);
  }
  /// The drive follows the face only while both are true: the output enable command (Modbus,
  /// OSC, monitor) and the GPIO enable switch (held closed; true while none is configured).
  std::atomic<bool> outputs_enabled{true};
  std::atomic<bool> enable_switch_closed{true};
  /// Per channel: a manual value in output units, or ChannelBank::kNoOverride (NaN).
  std::array<std::atomic<double>, kMaxChannels> overrides;
  std::atomic<std::uint32_t> calibrate_requests{0};  // +1 per request; acted on when it changes
  std::atomic<int> recording_request{-1};            // 1 start, 0 stop, -1 none (the daemon resets it)
};

/// The channels an output sends, as indices into DriveFrame::values: `names` in that order
/// (find_channel), or every channel when `names` is empty. Throws std::invalid_argument
/// "<output>: unknown channel 'x' (channels: a, b, ...)".
std::vector<int> pick_channels(std::span<const std::string> names, std::span<const ChannelSpec> channels,
                               std::string_view output);

}  // namespace lipdrive
